"""Named sizes of the generated Cityscapes-like dataset.

``demo`` is what the comparison harness's older tables (docs/accuracy.md)
were measured on (and what ``tools/demo.sh`` trained on until
2026-11-26): 128x256 images, most objects COCO-small, where every recipe
scores 1-5 AP. ``bench`` is the benchmark of the comparison tables, chosen by
measurement (docs/accuracy.md, "The benchmark"): 256x512 images (a
quarter of Cityscapes' side), objects from 48 px tall (nearer than about
20 m) at half the demo's density, 200 train / 50 val images; the
comparison harness's ``--preset bench`` gives the budget that goes with
it, and ``tools/demo.sh`` trains on it at half its side.

Each preset is the keyword arguments of
:func:`~cbnet_tools.synthetic.generate_cityscapes_like`.
"""
from typing import Dict

DATA_PRESETS: Dict[str, dict] = {
    'demo':
    dict(num_train=48, num_val=12, img_size=(128, 256), min_height_px=8.0,
         density=1.0),
    'bench':
    # candidate C of docs/accuracy.md "The benchmark": 48 px (B: 32 px,
    # density 0.6; A: 16 px, density 1) scored the most at equal budget
    dict(num_train=200, num_val=50, img_size=(256, 512),
         min_height_px=48.0, density=0.5),
}
