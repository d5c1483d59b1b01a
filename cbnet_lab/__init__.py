"""The experiment lab of cbnet_mmdet: what measures the models, apart from
the plugin (``cbnet_mmdet``: registered components only).

- :mod:`cbnet_lab.recipe_comparison`: the comparison harness
  (``tools/analysis_tools/compare_recipes.py`` is its command line), split
  by what it does: :mod:`cbnet_lab.sets` (the experiment files, a
  comparison's recipes), :mod:`cbnet_lab.plan` (its runs, checked before
  the first), :mod:`cbnet_lab.run` and :mod:`cbnet_lab.run_files` (one
  run: train, test, its result file, resume), :mod:`cbnet_lab.executors`
  (in this process, in N worker processes, as Ray tasks),
  :mod:`cbnet_lab.summary` (mean +- std over seeds, the record).
- :mod:`cbnet_lab.config_edits`: every config edit of the lab, composed
  once per run: a run's training config from a recipe, a budget and a
  seed (and where a killed run resumes), a checkpoint's test configs
  (clear / foggy / real fog / corrupted), the benchmarks' weightless
  build; the measurements below are handed finished configs.
- :mod:`cbnet_lab.report`: the tables and plots of a comparison and the
  machine line of every measurement.
- :mod:`cbnet_lab.ap_drop`: AP on clear vs foggy (and real-fog) test sets;
  ``tools/analysis_tools/ap_drop.py``.
- :mod:`cbnet_lab.robustness`: the corruption benchmark (mPC, rPC) next to
  the fog sweep; ``tools/analysis_tools/test_robustness.py``.
- :mod:`cbnet_lab.model_benchmark`: several detectors' speed, memory and
  FLOPs in one alternated run (``tools/analysis_tools/benchmark.py``), on
  the measurement helpers of :mod:`cbnet_lab.benchmark` (timing, timing
  in alternation, peak memory, FLOPs, realistic proposals), which the
  profiler and the component benchmarks use too.
- :mod:`cbnet_lab.profiling`: where a detector's time goes (timed calls,
  one ``torch.profiler`` call with a range per part);
  ``tools/analysis_tools/profile_model.py``.
- :mod:`cbnet_lab.component_benchmark`: parts of the model against what
  they replace, timed in alternation: the custom kernels
  (``benchmark_kernels.py``), the boundary-aware mask loss
  (``benchmark_mask_loss.py``), MiT's positional encodings
  (``benchmark_backbone.py``).
- :mod:`cbnet_lab.proposal_quality`: what a trained RPN hands its RoI
  heads (recall of the ground truth, share of positives);
  ``tools/analysis_tools/proposal_quality.py``.
- :mod:`cbnet_lab.metric_keys`: the reported metrics, named once.

Installed with the plugin (the tools import it), never imported by it.
"""
