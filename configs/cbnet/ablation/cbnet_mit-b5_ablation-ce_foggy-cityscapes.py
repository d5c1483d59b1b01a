# Table 3, row 1 ("baseline"): plain per-pixel cross-entropy mask loss, no
# Dice term, no Hausdorff edge term. Same data pipeline as the other rows.
_base_ = './cbnet_mit-b5_ablation-shape-edge_foggy-cityscapes.py'

model = dict(
    roi_head=dict(
        mask_head=dict(
            loss_mask=dict(use_shape=False, use_edge=False))))
