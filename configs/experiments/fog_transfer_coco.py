# Does training with synthetic fog carry over to real fog from a COCO
# start? The fog_transfer question asked again on COCO-pretrained models
# (fetch_pretrained.py yolox_nano): trained on the CLEAR COCO street
# photos, tested on COCO street val (clear) and on DAWN's fog + haze val
# (real fog, boxes). The stock Cascade Mask R-CNN on YOLOX-Nano's COCO
# trunk (the realfog_coco_trunk set's stock row; a fresh FPN, heads new):
# clear only, + synthetic fog augmentation, CBNet-DD on synthetic foggy
# twins, the dark channel prior and the peer's learned dehazer in front of
# the clear row's checkpoint at test time (trains nothing). Then
# YOLOX-Nano from COCO whole (box-only: no CBNet-DD, which distils mask
# logits): clear only, + fog augmentation, and the two dehazers in front
# (docs/robustness.md, "Synthetic fog to real fog from a COCO start").
preset = 'fog_transfer'
columns = ['box AP', 'box AP50']
recipes = [
    dict(
        name='Cascade Mask R-CNN, COCO trunk, clear',
        config='coco_trunk/fog_transfer/'
        'cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft_coco-street-to-'
        'dawn-fog.py'),
    dict(
        name='Cascade Mask R-CNN, COCO trunk, clear + fog aug',
        config='coco_trunk/fog_transfer/'
        'cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft-fog-aug_coco-'
        'street-to-dawn-fog.py'),
    dict(
        name='Cascade Mask R-CNN, COCO trunk, CBNet-DD',
        config='coco_trunk/fog_transfer/'
        'cascade-mask-rcnn-dd_yolox-nano-coco_fpn_1xb2-ft_coco-street-'
        'to-dawn-fog.py'),
    dict(
        name='DCP + Cascade Mask R-CNN, COCO trunk, clear (test only)',
        config='../projects/peer_dehaze/configs/coco_trunk/fog_transfer/'
        'cascade-mask-rcnn_yolox-nano-coco_fpn_dcp-test_coco-street-to-'
        'dawn-fog.py',
        weights_of='Cascade Mask R-CNN, COCO trunk, clear'),
    dict(
        name='dehazer + Cascade Mask R-CNN, COCO trunk, clear (test only)',
        config='../projects/peer_dehaze/configs/coco_trunk/fog_transfer/'
        'cascade-mask-rcnn_yolox-nano-coco_fpn_dehazer-test_coco-street-'
        'to-dawn-fog.py',
        weights_of='Cascade Mask R-CNN, COCO trunk, clear'),
    # YOLOX-Nano's rows: the preset's images seen (1290 iterations of 2)
    # in 645 iterations of 4, the batch its configs' lr is set for
    dict(
        name='YOLOX-Nano COCO, clear',
        config='yolox_coco/fog_transfer/'
        'yolox_nano_coco-ft_1xb4-36e_coco-street-to-dawn-fog.py',
        budget=dict(batch_size=4, iters_scale=0.5)),
    dict(
        name='YOLOX-Nano COCO, clear + fog aug',
        config='yolox_coco/fog_transfer/'
        'yolox_nano_coco-ft-fog-aug_1xb4-36e_coco-street-to-dawn-fog.py',
        budget=dict(batch_size=4, iters_scale=0.5)),
    dict(
        name='DCP + YOLOX-Nano COCO, clear (test only)',
        config='../projects/peer_dehaze/configs/yolox_coco/fog_transfer/'
        'yolox_nano_coco-ft_dcp-test_coco-street-to-dawn-fog.py',
        weights_of='YOLOX-Nano COCO, clear',
        budget=dict(batch_size=4, iters_scale=0.5)),
    dict(
        name='dehazer + YOLOX-Nano COCO, clear (test only)',
        config='../projects/peer_dehaze/configs/yolox_coco/fog_transfer/'
        'yolox_nano_coco-ft_dehazer-test_coco-street-to-dawn-fog.py',
        weights_of='YOLOX-Nano COCO, clear',
        budget=dict(batch_size=4, iters_scale=0.5)),
]
# every run is tested on its own test set, then on DAWN's fog and haze val
# photos (real fog; --transfer-root, the preset's, moves the folder), as
# the fog_transfer set tests them: the same 65 val photos the in-domain
# ceilings are tested on
transfer_test = dict(condition='real fog', data_root='data/dawn_fog/',
                     split='val', val_fraction=0.3, split_seed=0)
# the in-domain ceiling, tabulated from another set's record and never
# retrained: the same trunk and heads trained on DAWN's own train split,
# box-only, tested on the same 65 val photos (YOLOX-Nano's: the
# realfog_coco set's fine-tuned row, docs/robustness.md)
ceiling = dict(
    set='realfog_coco_trunk',
    condition='real fog',
    what=("the same trunk and heads, box-only, trained on DAWN's own "
          'train split'),
    rows={'Cascade Mask R-CNN, COCO trunk': 'Cascade R-CNN, COCO trunk'})
# the clear floor trains exactly as the coco_street_coco_trunk set's row
# (its config adds test settings only): with --weights-from (that set's
# work dir) its finished runs are tested instead of trained again
trained_as = dict(
    set='coco_street_coco_trunk',
    rows={'Cascade Mask R-CNN, COCO trunk, clear':
          'Cascade Mask R-CNN, COCO trunk'})
# on the lent GPU (tools/device/run_all.py) --pretrained must hold the
# converted YOLOX-Nano (without it the dry run writes seeded stand-ins);
# the learned dehazer's rows read its checkpoint, carried with the call
device = dict(
    dry_row='Cascade Mask R-CNN, COCO trunk, clear',
    tiny_weights='cbnet_tools.synthetic.yolox_checkpoints:tiny_yolox_nano',
    needs=['work_dirs/dehaze/dehazer_attention_1xb4-200it_cityscapes-like/'
           'iter_200.pth'])
