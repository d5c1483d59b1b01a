# MMDetection's runtime (hooks, logging, visualiser). The plugin import
# (`custom_imports`) comes with the dataset bases in _base_/datasets/.
_base_ = 'mmdet::_base_/default_runtime.py'

# the runner that loads checkpoints with the project's checks (the file
# named with its problem, weights-only with MMEngine's allow-list, no
# diverged checkpoint resumed): MMDet's tools/train.py and mim train build
# it as tools/train.py does (docs/reliability.md). `mmdet.`: MMEngine's
# RUNNERS.build looks a bare name up in its root registry only
runner_type = 'mmdet.CBNetRunner'

# default_hooks rather than custom_hooks: a child config that sets its own
# custom_hooks (CBNet-DD's teacher hook) keeps these (docs/reliability.md)
default_hooks = dict(
    # keep the best segm checkpoint and the last 3 epochs
    checkpoint=dict(
        type='CheckpointHook', interval=1, max_keep_ckpts=3,
        save_best='coco/segm_mAP', rule='greater'),
    logger=dict(type='LoggerHook', interval=50),
    # identical BN statistics on every rank in multi-process training
    sync_buffers=dict(type='SyncBuffersHook'),
    # RNG states in the checkpoint, so --resume continues bit for bit
    rng_state=dict(type='CBNetRNGStateHook'),
    # stop at the first NaN/Inf loss, naming iteration, loss and images
    non_finite=dict(type='CBNetNonFiniteLossHook'),
    # log what a load_from/resume checkpoint did not fill
    checkpoint_report=dict(type='CBNetCheckpointReportHook'),
    # checkpoints that torch.load's default weights_only reads without
    # cbnet_mmdet imported (DetInferencer(weights=CKPT) alone)
    weights_only=dict(type='CBNetWeightsOnlyCheckpointHook'))
