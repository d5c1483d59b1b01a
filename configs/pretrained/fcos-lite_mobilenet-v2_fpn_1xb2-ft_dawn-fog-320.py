# The earlier edge model (projects/edge_serving/README.md "The earlier
# edge model: FCOS-lite"): the light FCOS on the pretrained MobileNetV2 at half the
# recipes' size, photos and frames resized to fit 320x240 (a 640x360
# camera frame is read at 320x180), which is what brings one CPU thread
# near 15 frames/s; the 640 px config it is based on measures what the
# halving costs in AP.
_base_ = './fcos-lite_mobilenet-v2_fpn_1xb2-ft_dawn-fog.py'

# (w, h), keep_ratio: fits inside. The comparison harness gives every other
# recipe its preset's size (640x480); this one's row keeps this one
# (keep_img_scale, configs/experiments/realfog_pretrained.py), as its input
# size is part of the model.
fog_img_scale = (320, 240)
train_dataloader = dict(
    dataset=dict(pipeline=[
        dict(t, scale=fog_img_scale) if t['type'] == 'Resize' else t
        for t in _base_.train_dataloader.dataset.pipeline
    ]))
val_dataloader = test_dataloader = dict(
    dataset=dict(pipeline=[
        dict(t, scale=fog_img_scale) if t['type'] == 'Resize' else t
        for t in _base_.test_dataloader.dataset.pipeline
    ]))
