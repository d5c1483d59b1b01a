# A COCO-pretrained detector on real fog: MMDet's YOLOX-Nano with Megvii's
# COCO weights (tools/model_converters/fetch_pretrained.py yolox_nano) on
# DAWN's fog + haze photos, the seeded split of every real-fog set (the
# same 65 val photos), 640x480 at most, 12 epochs of the 152 training
# photos: zero-shot (the floor every real-fog row is read against), fine-
# tuned from COCO, the fine-tuning settings measured one at a time against
# it (a fresh classifier, 416 px, no EMA, batch norms trained, mosaic, 24
# epochs), rendered fog as augmentation, and the peer's dehaze-then-detect
# (the dark channel prior in front, and the peer's learned dehazer, trained
# on the generated pairs, in front of the fine-tuned weights) on it
# (docs/robustness.md, "A COCO-pretrained detector").
preset = 'realfog_coco'
columns = ['box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
recipes = [
    dict(name='YOLOX-Nano COCO, zero-shot',
         config='yolox_coco/yolox_nano_coco-zero-shot_dawn-fog.py',
         test_only=True),
    dict(name='YOLOX-Nano COCO, fine-tuned',
         config='yolox_coco/yolox_nano_coco-ft_1xb4-12e_dawn-fog.py'),
    dict(name='YOLOX-Nano COCO, fine-tuned, fresh classifier',
         config='yolox_coco/'
         'yolox_nano_coco-ft-fresh-cls_1xb4-12e_dawn-fog.py'),
    # the config's 416x312 (YOLOX-Nano's own COCO size), not the preset's
    dict(name='YOLOX-Nano COCO, fine-tuned, 416 px',
         config='yolox_coco/yolox_nano_coco-ft_1xb4-12e_dawn-fog-416.py',
         keep_img_scale=True),
    dict(name='YOLOX-Nano COCO, fine-tuned, no EMA',
         config='yolox_coco/yolox_nano_coco-ft-no-ema_1xb4-12e_dawn-fog.py'),
    dict(name='YOLOX-Nano COCO, fine-tuned, batch norms trained',
         config='yolox_coco/'
         'yolox_nano_coco-ft-bn-train_1xb4-12e_dawn-fog.py'),
    dict(name='YOLOX-Nano COCO, fine-tuned, mosaic',
         config='yolox_coco/yolox_nano_coco-ft-mosaic_1xb4-12e_dawn-fog.py'),
    # the same recipe twice as long: 24 epochs (900 iterations of 4)
    dict(name='YOLOX-Nano COCO, fine-tuned, 24 epochs',
         config='yolox_coco/yolox_nano_coco-ft_1xb4-12e_dawn-fog.py',
         budget=dict(iters_scale=2)),
    dict(name='YOLOX-Nano COCO, fine-tuned + fog aug',
         config='yolox_coco/'
         'yolox_nano_coco-ft-fog-aug_1xb4-12e_dawn-fog.py'),
    dict(name='DCP + YOLOX-Nano COCO, zero-shot',
         config='../projects/peer_dehaze/configs/yolox_coco/'
         'yolox_nano_coco-zero-shot_dcp_dawn-fog.py',
         test_only=True),
    dict(name='DCP + YOLOX-Nano COCO, fine-tuned',
         config='../projects/peer_dehaze/configs/yolox_coco/'
         'yolox_nano_coco-ft_dcp_1xb4-12e_dawn-fog.py'),
    dict(name='dehazer + YOLOX-Nano COCO, zero-shot',
         config='../projects/peer_dehaze/configs/yolox_coco/'
         'yolox_nano_coco-zero-shot_dehazer_dawn-fog.py',
         test_only=True),
    # the fine-tuned row trained again (same config, budget and seeds) for
    # the learned dehazer's row below, which tests its weights: it did not
    # reproduce the fine-tuned row's scores (docs/robustness.md)
    dict(name='YOLOX-Nano COCO, fine-tuned, rerun',
         config='yolox_coco/yolox_nano_coco-ft_1xb4-12e_dawn-fog.py'),
    # the rerun's weights of each seed, the dehazer in front at test time
    # only (training behind it: 28 s an iteration here, not run)
    dict(name='dehazer + YOLOX-Nano COCO, fine-tuned (test only)',
         config='../projects/peer_dehaze/configs/yolox_coco/'
         'yolox_nano_coco-ft_dehazer-test_dawn-fog.py',
         weights_of='YOLOX-Nano COCO, fine-tuned, rerun'),
]
# on the lent GPU (tools/device/run_all.py) --pretrained must hold the two
# files of fetch_pretrained.py yolox_nano; without it the dry run writes
# seeded stand-ins of both; the learned dehazer's rows read its checkpoint,
# carried with the call
device = dict(
    dry_row='YOLOX-Nano COCO, fine-tuned',
    needs=['work_dirs/dehaze/dehazer_attention_1xb4-200it_cityscapes-like/'
           'iter_200.pth'],
    tiny_weights='cbnet_tools.synthetic.yolox_checkpoints:tiny_yolox_nano')
