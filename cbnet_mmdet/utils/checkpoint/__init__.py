"""Checkpoints, in one place: what the project does with a checkpoint file.

- :mod:`.files`: the file check (a PNG passed as the checkpoint is named
  as such), checked weights-only reading, resuming (``last_checkpoint``,
  the newest intact file, never one written after training diverged),
  publishing (SHA-256 name) and CBNet-DD student export;
- :mod:`.safe_globals`: the exact allow-list that lets
  ``torch.load(weights_only=True)`` read MMEngine checkpoints, as a context
  (never for the whole process);
- :mod:`.fit`: does a checkpoint fit a model (refused by ``tools/test.py``
  and the project's tools, reported after ``load_from``).

``CBNetRunner`` (``engine/runner/``) is where training and testing load
through them. Whoever loads them, the CBNet trunk, neck and Cascade RPN
refuse tensors that do not fit them (``models/utils/state_dict_fit.py``).
Model-specific key maps stay with their model (the SegFormer MiT layout:
``models/backbones/mit_checkpoint.py``; the peer baseline's dehazer: its
project).
"""
