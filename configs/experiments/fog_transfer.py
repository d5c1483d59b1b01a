# Does training with synthetic fog carry over to real fog? Trained on the
# CLEAR COCO street photos (with their masks: CBNet-DD distils mask
# logits), tested on COCO street val (clear) and on DAWN's fog + haze val
# (real fog, boxes): the floor, synthetic fog augmentation, CBNet-DD on
# synthetic foggy twins, and the dark channel prior and the peer's learned
# dehazer (realfog's, trained on the generated pairs) in front of the
# floor's own checkpoint at test time (trains nothing), on the stock
# cascade and on CBNet-PT (docs/robustness.md).
preset = 'fog_transfer'
columns = ['box AP', 'box AP50']
recipes = [
    dict(
        name='Cascade Mask R-CNN, clear',
        config='pretrained/fog_transfer/'
        'cascade-mask-rcnn_mobilenet-v2_fpn_1xb2-ft_coco-street-to-'
        'dawn-fog.py'),
    dict(
        name='Cascade Mask R-CNN, clear + fog aug',
        config='pretrained/fog_transfer/'
        'cascade-mask-rcnn_mobilenet-v2_fpn_1xb2-ft-fog-aug_coco-'
        'street-to-dawn-fog.py'),
    dict(
        name='Cascade Mask R-CNN, CBNet-DD',
        config='pretrained/fog_transfer/'
        'cascade-mask-rcnn-dd_mobilenet-v2_fpn_1xb2-ft_coco-street-'
        'to-dawn-fog.py'),
    dict(
        name='DCP + Cascade Mask R-CNN, clear (test only)',
        config='../projects/peer_dehaze/configs/pretrained/fog_transfer/'
        'cascade-mask-rcnn_mobilenet-v2_fpn_dcp-test_coco-street-to-'
        'dawn-fog.py',
        weights_of='Cascade Mask R-CNN, clear'),
    dict(
        name='dehazer + Cascade Mask R-CNN, clear (test only)',
        config='../projects/peer_dehaze/configs/pretrained/fog_transfer/'
        'cascade-mask-rcnn_mobilenet-v2_fpn_dehazer-test_coco-street-'
        'to-dawn-fog.py',
        weights_of='Cascade Mask R-CNN, clear'),
    dict(
        name='CBNet-PT, clear',
        config='pretrained/fog_transfer/'
        'cbnet-pt_mobilenet-v2_fpn-crpn_1xb2-ft_coco-street-to-dawn-'
        'fog.py'),
    dict(
        name='CBNet-PT, clear + fog aug',
        config='pretrained/fog_transfer/'
        'cbnet-pt_mobilenet-v2_fpn-crpn_1xb2-ft-fog-aug_coco-street-'
        'to-dawn-fog.py'),
    dict(
        name='CBNet-PT, CBNet-DD',
        config='pretrained/fog_transfer/'
        'cbnet-pt-dd_mobilenet-v2_fpn-crpn_1xb2-ft_coco-street-to-'
        'dawn-fog.py'),
    dict(
        name='DCP + CBNet-PT, clear (test only)',
        config='../projects/peer_dehaze/configs/pretrained/fog_transfer/'
        'cbnet-pt_mobilenet-v2_fpn-crpn_dcp-test_coco-street-to-dawn-'
        'fog.py',
        weights_of='CBNet-PT, clear'),
    dict(
        name='dehazer + CBNet-PT, clear (test only)',
        config='../projects/peer_dehaze/configs/pretrained/fog_transfer/'
        'cbnet-pt_mobilenet-v2_fpn-crpn_dehazer-test_coco-street-to-'
        'dawn-fog.py',
        weights_of='CBNet-PT, clear'),
]
# every run is tested on its own test set, then on DAWN's fog and haze val
# photos (real fog; --transfer-root, the preset's, moves the folder): the
# recipe's own test pipeline, boxes only (cbnet_lab.config_edits
# .real_fog_cfg), DAWN's VOC names read as the project's 8 classes, the
# seeded split of configs/realfog/_base_/voc-fog_box.py (30 % val, seed 0):
# the same 65 val photos the realfog_pretrained set (the in-domain ceiling)
# is tested on
transfer_test = dict(condition='real fog', data_root='data/dawn_fog/',
                     split='val', val_fraction=0.3, split_seed=0)
# the in-domain ceiling, tabulated from another set's record and never
# retrained: the same trunk and heads trained on DAWN's own train split,
# box-only, tested on the same 65 val photos (rows: by the prefix of this
# set's row names)
ceiling = dict(
    set='realfog_pretrained',
    condition='real fog',
    what=("the same trunk and heads, box-only, trained on DAWN's own "
          'train split'),
    rows={'Cascade Mask R-CNN': 'Cascade R-CNN', 'CBNet-PT': 'CBNet-PT'})
# rows that train exactly as rows of another set (their configs add test
# settings only, checked): with --weights-from (that set's work dir) their
# finished runs are tested instead of trained again; here the clear-only
# floor is the coco_street recipe with DAWN as a second test set
trained_as = dict(
    set='coco_street',
    rows={
        'Cascade Mask R-CNN, clear': 'Cascade Mask R-CNN',
        'CBNet-PT, clear': 'CBNet-PT',
    })
# the row the lent GPU script's dry run trains (tools/device/run_all.py),
# tested on a tiny fog folder too; the learned dehazer's rows read its
# checkpoint, carried with the call
device = dict(
    dry_row='Cascade Mask R-CNN, clear',
    needs=['work_dirs/dehaze/dehazer_attention_1xb4-200it_cityscapes-like/'
           'iter_200.pth'])
