# CBNet-DD on the COCO-trunk Cascade Mask R-CNN (fog_transfer_coco set):
# the floor's model as the student, fed each clear photo's synthetic foggy
# twin (CBNetAddFoggyTwin, beta uniform in 0.005-0.02 1/m, every image
# fogged), and an EMA teacher fed the clear photo with the same resize and
# flip; their last-stage mask logits on the student's RoIs are distilled
# (paper II.E, (11)). Tested as the student on 3-channel photos, clear and
# real fog, like the other rows.
_base_ = ('./cascade-mask-rcnn_yolox-nano-coco_fpn_'
          '1xb2-ft_coco-street-to-dawn-fog.py')

# the clear row's model as the student, with its input (raw 0-255 BGR, as
# the trunk was trained) and padding for the stacked foggy (channels 0-2) +
# clear (3-5) image
model = dict(
    _delete_=True,
    detector=_base_.model,
    data_preprocessor=dict(
        _base_.model.data_preprocessor, type='CBNetPairedDataPreprocessor'),
    **_base_.transfer_distiller)
custom_hooks = _base_.transfer_teacher_hooks  # EMA momentum 0.99
# no photometric transform or Pad after the twin: both halves alike
train_dataloader = dict(
    dataset=dict(pipeline=_base_.street_train_pipeline[:2] +
                 [_base_.transfer_twin] + _base_.street_train_pipeline[2:]))
