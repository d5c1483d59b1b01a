# The fine-tuned YOLOX-Nano with its batch norms in train mode (MMDet's
# default): batch statistics of 4 photos replace the running statistics.
# With the ONNX weights, whose batch norms were folded into the
# convolutions (running mean 0, variance 1 - eps), this is the collapse
# that CBNetNormEvalHook prevents; kept as the measurement of why.
_base_ = './yolox_nano_coco-ft_1xb4-12e_dawn-fog.py'

custom_hooks = [
    dict(type='EMAHook', ema_type='ExpMomentumEMA', momentum=0.0001,
         update_buffers=True, priority=49)
]
