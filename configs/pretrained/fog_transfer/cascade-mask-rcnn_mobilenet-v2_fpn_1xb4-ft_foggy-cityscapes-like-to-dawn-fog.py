# Generated -> real: the same model trained on the generated
# scenes' depth-rendered fog (beta 0.02, Foggy Cityscapes' benchmark density,
# as the ablation set trains), tested as the clear row: how far rendered fog is
# from real fog.
_base_ = ('./cascade-mask-rcnn_mobilenet-v2_fpn_'
          '1xb4-ft_cityscapes-like-to-dawn-fog.py')

train_dataloader = dict(
    dataset=dict(
        dataset=dict(type='CBNetFoggyCityscapesDataset', beta=0.02)))
