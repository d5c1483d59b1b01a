"""Shared fixtures.

``cityscapes_like_root``: a tiny generated Cityscapes / Foggy Cityscapes
tree (4 train + 3 val images at 128x256, seed 0; image 2 of each split has
no instances, images 0 of each split have a crowd region), converted to COCO
JSON under ``{root}/annotations/instancesonly_filtered_gtFine_{split}.json``.
Generated once per test session (about 2 s) into its own temporary folder
(not pytest's ``tmp_path_factory``, whose old numbered folders a concurrent
pytest run may delete), removed at the end of the session.
"""
import os.path as osp
import tempfile

import pytest

#: Parameters of the tiny dataset (tests may rely on them).
TINY = dict(num_train=4, num_val=3, img_size=(128, 256), seed=0,
            empty_every=3, crowd_every=2)


@pytest.fixture(scope='session')
def cityscapes_like_root():
    """Root of the tiny generated dataset, annotations converted."""
    from cbnet_mmdet.datasets.cityscapes_to_coco import convert
    from cbnet_mmdet.datasets.synthetic import generate_cityscapes_like
    with tempfile.TemporaryDirectory(prefix='cbnet_cityscapes_like_') as tmp:
        root = osp.join(tmp, 'cityscapes')
        generate_cityscapes_like(root, **TINY)
        convert(root)
        assert osp.isfile(
            osp.join(root, 'annotations',
                     'instancesonly_filtered_gtFine_val.json'))
        yield root
