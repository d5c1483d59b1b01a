# The training-free baseline: He et al.'s dark channel prior with guided-
# filter refinement (CBNetDarkChannelPrior), evaluated like the learned
# dehazer (the tool skips training: it has no parameters).
_base_ = './dehazer_attention_1xb4-600it_cityscapes-like.py'

model = dict(
    dehazer=dict(
        _delete_=True,
        type='CBNetDarkChannelPrior',
        patch_size=15,  # He et al.
        guided_radius=40))  # see DarkChannelPrior's docstring
