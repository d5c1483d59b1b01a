# The revised CBNet's box path at the full trunk lr with its NAS-FPN's
# BatchNorm replaced by GroupNorm, nothing else changed
# (compare_recipes.py --set realfog_pretrained_neck, docs/robustness.md).
# The question: the neck, trained from scratch in training mode on batches
# of 2 photos, normalises every convolution with those 2 photos' batch
# statistics (the trunk's BN is frozen by norm_eval, FPN has no norm at
# all); does that cost CBNet on real fog, where the parts set's seed 0
# put NAS-FPN's cost? GroupNorm does not depend on the batch.
_base_ = ('../finetune/cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-'
          'trunk-lr1_dawn-fog.py')
model = dict(
    neck=dict(
        # 8 groups of 8 channels at the neck's 64 (MMDet's GN configs: 32
        # groups of 8 at 256)
        norm_cfg=dict(type='GN', num_groups=8, requires_grad=True)))
