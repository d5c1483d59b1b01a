"""The steps of ``tools/device/run_all.py``, one call on a lent GPU machine
(standard library only): ``runner`` (time boxes, records, the packed
output), ``stack`` (set-up), ``cuda_tests``, ``speed``, ``harness`` over
``plans`` (each set's plan, read from its file in ``configs/experiments/``)
and ``prepare`` (``--prepare``)."""
