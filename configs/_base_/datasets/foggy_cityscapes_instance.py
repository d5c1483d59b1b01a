# Foggy Cityscapes: the Cityscapes annotations on
# leftImg8bit_foggy/*_leftImg8bit_foggy_beta_{beta}.png (same data_root).
# beta is the fog attenuation coefficient in 1/m: 0.02 is the common
# benchmark (visibility 150 m), the paper's figures use 0.01. To change it
# from the command line set all three:
#   --cfg-options train_dataloader.dataset.dataset.beta=0.01 \
#       val_dataloader.dataset.beta=0.01 test_dataloader.dataset.beta=0.01
_base_ = './cityscapes_instance.py'

beta = 0.02
foggy_dataset = dict(type='CBNetFoggyCityscapesDataset', beta=beta)

train_dataloader = dict(dataset=dict(dataset=foggy_dataset))
val_dataloader = dict(dataset=foggy_dataset)
test_dataloader = val_dataloader
