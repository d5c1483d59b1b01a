"""Checkpoints, in one place: what the plugin does with a checkpoint file.

- :mod:`.file_check`: refuse a file that is not a PyTorch checkpoint,
  naming it (MMEngine's local loader, checked first);
- :mod:`.safe_globals`: the exact allow-list that lets
  ``torch.load(weights_only=True)`` read MMEngine checkpoints;
- :mod:`.files`: checked reading, resuming (``last_checkpoint``, the newest
  intact file), publishing (SHA-256 name) and CBNet-DD student export;
- :mod:`.fit`: does a checkpoint fit a model (refused at inference when it
  does not, reported after ``load_from``).

Model-specific key maps stay with their model (the SegFormer MiT
layout: ``models/backbones/mit_checkpoint.py``; the peer baseline's
dehazer: its project).
"""
