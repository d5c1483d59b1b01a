"""The experiment lab of cbnet_mmdet: what measures the models, apart from
the plugin (``cbnet_mmdet``: registered components only).

- :mod:`cbnet_lab.recipe_comparison`: the comparison harness (recipe sets,
  training and testing runs, statistics over seeds, tables and plots);
  ``tools/analysis_tools/compare_recipes.py`` is its command line.
- :mod:`cbnet_lab.ap_drop`: AP on clear vs foggy (and real-fog) test sets;
  ``tools/analysis_tools/ap_drop.py``.
- :mod:`cbnet_lab.robustness`: the corruption benchmark (mPC, rPC) next to
  the fog sweep; ``tools/analysis_tools/test_robustness.py``.
- :mod:`cbnet_lab.benchmark`: speed, memory and FLOPs measurement;
  ``tools/analysis_tools/benchmark.py``, ``profile_model.py`` and the
  component benchmarks.

Installed with the plugin (the tools import it), never imported by it.
"""
