from .checkpoint.safe_globals import allow_mmengine_checkpoints
from .version_check import check_versions

__all__ = ['allow_mmengine_checkpoints', 'check_versions']
