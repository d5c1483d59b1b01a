# Does training with synthetic fog carry over to real fog?
# (compare_recipes.py --set fog_transfer, docs/robustness.md "Synthetic fog
# to real fog"). A second base next to a coco_street recipe, keys prefixed
# `transfer_`: the recipes train on the CLEAR COCO street photos
# (coco-street_instance.py, with their masks: CBNet-DD distils mask logits);
# the harness tests each checkpoint on the config's own test set (COCO
# street val, clear) and on the set's second test set, DAWN's real fog
# (configs/experiments/fog_transfer.py, its transfer_test).

# Synthetic fog for the clear training photos (CBNetAddFog's row prior, no
# depth needed): beta drawn per image in Foggy Cityscapes' range, 0.005 to
# 0.02 1/m (visibility 600 m to 150 m; its three densities are 0.005, 0.01,
# 0.02). The augmentation fogs half of the images (prob 0.5), so the clear
# photos the floor trains on stay in the mix; CBNet-DD's twin is always
# foggy (the student sees fog, its EMA teacher the clear original).
transfer_fog_beta = (0.005, 0.02)
transfer_fog = dict(type='CBNetAddFog', beta=transfer_fog_beta, prob=0.5)
transfer_twin = dict(type='CBNetAddFoggyTwin', beta=transfer_fog_beta)
# CBNet-DD (the `-dd_` configs): the distiller's settings besides its
# student (the clear row's model) and data preprocessor. The teacher
# starts as a copy of the student (the paper config's
# teacher_checkpoint=None) and keeps 99 % of itself each step: the paper's
# 0.999 averages over ~1000 steps, most of the 1290-iteration budget (at
# 0.999 the teacher would still be 0.999^1290 = 28 % its untrained heads
# at the end); 0.99 forgets them within ~100 steps.
transfer_distiller = dict(
    type='CBNetDistiller',
    distill_loss=dict(type='CBNetDistillLoss', loss_weight=1.0),
    eval_with='student')
transfer_teacher_hooks = [
    dict(type='CBNetTeacherEMAHook', momentum=0.99, interval=1)
]
