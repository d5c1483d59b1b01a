# Real fog for the pretrained recipes: the data of the realfog
# set (configs/realfog/_base_/voc-fog_box.py: DAWN's fog and haze photos or
# any VOC folder, read by CBNetVOCFogDataset as the 8 Cityscapes classes,
# its seeded split: 30 % val, seed 0, the same 65 val photos; boxes only;
# keys prefixed `fog_`, copied over by the recipe configs) with three
# changes: photos at most 640x480 (every 1280-wide DAWN photo becomes 640
# wide; at 256 px the distant vehicles were a few pixels), batches of 2,
# and the checked loader named in the training pipeline (an unreadable
# image is an error naming the file).
_base_ = '../../../realfog/_base_/voc-fog_box.py'

fog_img_scale = (640, 480)  # (w, h), keep_ratio: fits inside
fog_train_pipeline = [dict(type='CBNetLoadImageFromFile')] + [
    dict(t, scale=fog_img_scale) if t['type'] == 'Resize' else t
    for t in _base_.fog_train_pipeline[1:]
]
fog_test_pipeline = [
    dict(t, scale=fog_img_scale) if t['type'] == 'Resize' else t
    for t in _base_.fog_test_pipeline
]
fog_train_dataloader = dict(
    batch_size=2, dataset=dict(pipeline=fog_train_pipeline))
fog_test_dataloader = dict(dataset=dict(pipeline=fog_test_pipeline))
