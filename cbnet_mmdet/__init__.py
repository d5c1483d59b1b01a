"""CBNet for MMDetection 3.x.

Importing the package (or listing it in a config's ``custom_imports``)
registers every component in MMDetection's registries.
"""
from .utils.version_check import check_versions
from .version import __version__

check_versions()

from .utils.checkpoint.safe_globals import allow_mmengine_checkpoints  # noqa: E402,E501,isort:skip

allow_mmengine_checkpoints()

from .utils.checkpoint.file_check import use_checked_local_loader  # noqa: E402,E501,isort:skip

use_checked_local_loader()  # a PNG passed as checkpoint: a clear error

from . import datasets, engine, evaluation, models  # noqa: E402,F401,E501,isort:skip

__all__ = ['__version__']
