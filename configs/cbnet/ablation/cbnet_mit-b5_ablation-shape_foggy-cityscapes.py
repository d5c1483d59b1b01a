# Table 3, row 2 ("+shape"): L_shape = BCE + (1 - Dice), no edge term. Same
# data pipeline as the other rows.
_base_ = './cbnet_mit-b5_ablation-shape-edge_foggy-cityscapes.py'

model = dict(
    roi_head=dict(
        mask_head=dict(
            loss_mask=dict(use_shape=True, use_edge=False))))
