# Table 3 at demo size, row 2 ("+shape"): L_shape = BCE + (1 - Dice), no
# edge term; data and pipeline as row 3.
_base_ = ('./cbnet_mit-b0_ablation-shape-edge_1xb4-demo_'
          'foggy-cityscapes-like.py')

model = dict(
    roi_head=dict(
        mask_head=dict(loss_mask=dict(use_shape=True, use_edge=False))))
