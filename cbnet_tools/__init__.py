"""The library of the command lines: what ``tools/`` (and the lab's and
the projects' reports) call that registers nothing, kept out of the
plugin (``cbnet_mmdet``: registered components and their helpers only).

- :mod:`cbnet_tools.synthetic`: the renderer of the generated
  Cityscapes-like scenes (clear, depth-fogged) and small PASCAL VOC
  folders; ``tools/misc/generate_cityscapes_like.py``.
- :mod:`cbnet_tools.cityscapes_to_coco`: Cityscapes ``gtFine`` instances
  to MMDetection's COCO JSON; ``tools/dataset_converters/cityscapes.py``.
- :mod:`cbnet_tools.coco_statistics`: what a COCO instance file holds;
  ``tools/misc/dataset_stats.py``.
- :mod:`cbnet_tools.pretrained`, :mod:`cbnet_tools.trunk_weights`: the
  ImageNet trunks' cache folder, fetch steps and key maps;
  ``tools/model_converters/fetch_pretrained.py``.
- :mod:`cbnet_tools.markdown`: the markdown tables every report prints.
- :mod:`cbnet_tools.cpu_distributed`: distributed launches on CPU-only
  machines, for ``tools/train.py`` and ``tools/test.py``.
- :mod:`cbnet_tools.measure`: wall time and peak memory of calls, what
  the lab's benchmarks and the peer baseline's ``benchmark_dehazer.py``
  time with.

Installed with the plugin, never imported by it; it imports the plugin
(dataset paths) and nothing of the lab or the projects
(``tests/test_layering.py``).
"""
