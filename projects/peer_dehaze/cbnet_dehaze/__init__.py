"""The peer baseline: dehaze-then-detect (YOLO-Vehicle-Pro's approach) as
MMDetection components, a project on top of the ``cbnet_mmdet`` plugin.

Importing the package (or listing it after ``cbnet_mmdet`` in a config's
``custom_imports``) registers its components in MMDetection's registries;
``cbnet_mmdet`` itself never imports it.
"""
from . import evaluation, models  # noqa: F401

__all__ = []
