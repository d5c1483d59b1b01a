# Table 3, row 1 ("baseline"): plain per-pixel cross-entropy mask loss, no
# Dice term, no Hausdorff edge term, no edge output supervision.
_base_ = '../cbnet_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes.py'

model = dict(
    roi_head=dict(
        mask_head=dict(
            loss_edge=None,
            loss_mask=dict(use_shape=False, use_edge=False))))
