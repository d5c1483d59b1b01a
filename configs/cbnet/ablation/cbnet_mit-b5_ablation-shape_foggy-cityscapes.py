# Table 3, row 2 ("+shape"): L_shape = BCE + (1 - Dice), no edge term.
_base_ = '../cbnet_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes.py'

model = dict(
    roi_head=dict(
        mask_head=dict(
            loss_edge=None,
            loss_mask=dict(use_shape=True, use_edge=False))))
