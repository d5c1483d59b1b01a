"""Named sizes of the generated Cityscapes-like dataset.

``demo`` is what ``tools/demo.sh`` used to train on and what the comparison
harness's older tables (docs/accuracy.md) were measured on: 128x256 images,
half the objects under 8x8 px, where every recipe scores 1-5 AP. ``bench``
is the benchmark of issue 23, chosen by measurement (docs/dataset.md,
"Benchmark preset") so that recipes can be told apart: 256x512 images (a
quarter of Cityscapes' side), objects from 16 px up, enough images for a
stable val AP; the comparison harness's ``--preset bench`` gives the
budget that goes with it.

Each preset is the keyword arguments of
:func:`~cbnet_mmdet.datasets.synthetic.generate_cityscapes_like`.
"""
from typing import Dict

DATA_PRESETS: Dict[str, dict] = {
    'demo':
    dict(num_train=48, num_val=12, img_size=(128, 256), min_height_px=8.0,
         density=1.0),
    'bench':
    dict(num_train=200, num_val=50, img_size=(256, 512),
         min_height_px=16.0, density=1.0),
}
