# The dehazers in front of the real-fog detectors (compare_recipes.py --set
# realfog), as a second base (keys prefixed `fog_`).
# The learned one: the project's demo CBNetAttentionDehazer trained on
# the generated clear/foggy pairs (never on real fog), for 200 iterations:
# train it first with ../dehazer_attention_1xb4-200it_cityscapes-like.py
# (its header has the command), which writes this checkpoint
fog_dehazer_checkpoint = ('work_dirs/dehaze/'
                          'dehazer_attention_1xb4-200it_cityscapes-like/'
                          'iter_200.pth')
# He et al.'s dark channel prior as ../dehazer_dcp_cityscapes-like.py has it
fog_dcp = dict(type='CBNetDarkChannelPrior', patch_size=15, guided_radius=40)
