# Table 3 at demo size, row 3 ("+shape +edge"): the demo CBNet (full
# boundary-aware loss) trained on the generated foggy images (beta 0.02,
# Foggy Cityscapes' benchmark density) and tested on foggy val. Rows 1 and 2
# inherit this file; row 4 (+KD) uses the same data and pipeline with the
# clear twin of each image for the teacher. Run the four with
# tools/analysis_tools/compare_recipes.py --set ablation.
_base_ = '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'

beta = 0.02
foggy = dict(type='CBNetFoggyCityscapesDataset', beta=beta)
train_dataloader = dict(dataset=dict(dataset=foggy))
val_dataloader = dict(dataset=foggy)
test_dataloader = val_dataloader
