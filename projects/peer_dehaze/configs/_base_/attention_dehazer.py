# The learned dehazer (CBNetAttentionDehazer, paper III-D) at the size used
# by the dehazer training configs and, frozen, in front of the detectors.
dehazer = dict(
    type='CBNetAttentionDehazer',
    channels=16,  # small default; the paper gives no width
    num_blocks=2)
# the demo dehazer: where projects/peer_dehaze/tools/train_dehazer.py writes
# the last checkpoint of dehazer_attention_1xb4-600it_cityscapes-like.py
dehaze_checkpoint = ('work_dirs/dehaze/'
                     'dehazer_attention_1xb4-600it_cityscapes-like/'
                     'iter_600.pth')
dehaze_preprocessor = dict(
    type='CBNetDehazeDataPreprocessor',
    dehaze=dehazer,
    dehaze_checkpoint=dehaze_checkpoint,
    train_dehazer=False)  # frozen: the dehazer is a fixed front end
# the same in front of the full-size detectors: the dehazer of
# dehazer_attention_8xb4-20k_foggy-cityscapes.py
cityscapes_dehaze_preprocessor = dict(
    dehaze_preprocessor,
    dehaze_checkpoint=('work_dirs/dehaze/'
                       'dehazer_attention_8xb4-20k_foggy-cityscapes/'
                       'iter_20000.pth'))
