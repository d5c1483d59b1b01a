"""Every config edit of the lab, in one place.

A measurement never rewrites a config itself: it is handed finished ones,
composed here once per run.

- :mod:`.training`: one run's training config from a recipe, a budget and
  a seed (:func:`budget_cfg`) and the edits it is made of (move the data,
  resize every pipeline), plus where a killed run resumes from.
- :mod:`.testing`: a checkpoint's test configs, each a test-only runner's
  (:func:`test_cfg`): clear / foggy val (:func:`condition_cfg`), real fog
  (:func:`real_fog_cfg`), a second test set (:func:`transfer_cfg`),
  corrupted images (:func:`corrupted_cfg`); composed for the AP drop
  (:func:`ap_drop_cfgs`) and for the corruption benchmark
  (:func:`robustness_cfgs`).
- :mod:`.weightless`: the benchmarks' and profiler's weightless build
  (:func:`load_benchmark_cfg`) and the optimiser of their timed steps.
- :mod:`.reading`: where the configs are and a parse cache
  (:func:`read_config`), which every edit starts from.

Each edit walks the whole config (wrapped or paired datasets, evaluator
lists), so a recipe's structure does not matter, and fails loudly when it
would silently not apply.
"""
from .reading import configs_root, read_config
from .testing import (CLEAR_TYPES, FOGGY_TYPE, LOADER_TYPES, PACK_META_KEYS,
                      REAL_FOG, ap_drop_cfgs, condition_cfg, corrupted_cfg,
                      default_betas, real_fog_cfg, robustness_cfgs, test_cfg,
                      transfer_cfg)
from .training import (ITER_CHECKPOINT, Budget, budget_cfg,
                       checkpoint_interval, checkpoint_iter,
                       replace_data_root, resume_file, set_img_scale)
from .weightless import load_benchmark_cfg, strip_pretrained, timing_optim_cfg

__all__ = [
    'configs_root', 'read_config', 'Budget', 'budget_cfg',
    'replace_data_root', 'set_img_scale', 'checkpoint_interval',
    'ITER_CHECKPOINT', 'resume_file', 'checkpoint_iter', 'CLEAR_TYPES',
    'FOGGY_TYPE', 'PACK_META_KEYS', 'LOADER_TYPES', 'REAL_FOG',
    'default_betas', 'condition_cfg', 'real_fog_cfg', 'transfer_cfg',
    'corrupted_cfg', 'test_cfg', 'ap_drop_cfgs', 'robustness_cfgs',
    'strip_pretrained', 'load_benchmark_cfg', 'timing_optim_cfg'
]
