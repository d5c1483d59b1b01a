# The fine-tuned YOLOX-Nano without the EMA of its weights: the last
# weights are tested (what MMDet's YOLOX recipe's EMAHook is worth here).
_base_ = './yolox_nano_coco-ft_1xb4-12e_dawn-fog.py'

custom_hooks = [dict(type='CBNetNormEvalHook')]
