from .checkpoint.safe_globals import mmengine_safe_globals
from .version_check import check_versions

__all__ = ['mmengine_safe_globals', 'check_versions']
