# The paper's unpaired objective (III-E2, after UCL-Dehaze): vanilla GAN
# loss against a PatchGAN shown clear images of *other* scenes, PatchNCE
# between the dehazer's features of the hazy input and of its output, and
# the identity loss. Real fog has no clear twin; the pairs of the generated
# data are used only for the PSNR/SSIM evaluation.
_base_ = './dehazer_attention_1xb4-600it_cityscapes-like.py'

model = dict(
    objective='unpaired',
    discriminator=dict(type='CBNetPatchDiscriminator', channels=32),
    # 64 sampled locations per 128x128 crop and feature layer (CUT: 256 on
    # 256x256)
    loss_nce=dict(type='CBNetPatchNCELoss', num_patches=64),
    adv_weight=1.0,  # CUT's lambda_GAN
    idt_weight=1.0)  # CUT's identity weight (lambda_NCE on idt patches)
