"""CBNet for MMDetection 3.x.

Importing the package (or listing it in a config's ``custom_imports``)
registers every component in MMDetection's registries, and does nothing
else: no MMEngine checkpoint loader replaced, no torch safe global added,
nothing registered outside the ``CBNet`` names
(``tests/test_import_inert.py``).
The checkpoint checks are opted into by the configs
(``configs/_base_/default_runtime.py``:
``runner_type='mmdet.CBNetRunner'`` and the reliability hooks;
docs/reliability.md).
"""
from .utils.version_check import check_versions
from .version import __version__

check_versions()

from . import datasets, engine, evaluation, models  # noqa: E402,F401,E501,isort:skip

__all__ = ['__version__']
