# The learned dehazer in front of the real-fog detectors (set realfog): the
# demo CBNetAttentionDehazer of the project, trained the same way on the
# generated clear/foggy pairs (never on real fog) but shorter, the run of
# the project's README: 200 iterations of 4 crops of 64x64 (about 10 min on a
# loaded 2-core CPU, against 23 min for the 600 of 128x128):
#   python tools/misc/generate_cityscapes_like.py data/cityscapes_like \
#       --convert
#   python projects/peer_dehaze/tools/train_dehazer.py THIS_CONFIG \
#       --data-root data/cityscapes_like
# writes work_dirs/dehaze/dehazer_attention_1xb4-200it_cityscapes-like/
# iter_200.pth, which _base_/dehazers.py loads.
_base_ = '../dehazer_attention_1xb4-600it_cityscapes-like.py'

max_iters = 200
crop_size = (64, 64)
train_dataloader = dict(
    dataset=dict(datasets=[
        dict(
            _base_.paired_train,
            beta=beta,
            pipeline=[
                dict(t, crop_size=crop_size)
                if t.type == 'RandomCrop' else t
                for t in _base_.train_pipeline
            ]) for beta in _base_.betas
    ]))
train_cfg = dict(max_iters=max_iters, val_interval=max_iters)
param_scheduler = [
    dict(type='LinearLR', start_factor=0.1, by_epoch=False, begin=0,
         end=50),
    dict(type='CosineAnnealingLR', by_epoch=False, begin=0, end=max_iters,
         T_max=max_iters)
]
default_hooks = dict(checkpoint=dict(interval=max_iters))
