# CBNet-PT's box path on real fog with the trunk fine-tuned at the neck's
# and heads' lr (AdamW 2e-4, lr_mult 1) instead of a tenth: the CBNet
# recipe for pretrained trunks as measured on DAWN's real fog, where the
# full trunk lr beat a tenth of it (docs/robustness.md). The same config
# as the real-fog parts set's row 'CBNet revised -NAS-FPN, trunk lr x1'
# (the revised CBNet at the full trunk lr with FPN in place of NAS-FPN),
# which keeps its name there. Weights, once: python
# tools/model_converters/fetch_pretrained.py mobilenet_v2.
_base_ = './cbnet-pt-box_mobilenet-v2_fpn-crpn_1xb2-ft_dawn-fog.py'
optim_wrapper = dict(
    paramwise_cfg=dict(custom_keys=dict(backbone=dict(lr_mult=1.0))))
