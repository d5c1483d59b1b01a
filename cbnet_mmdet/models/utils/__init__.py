from .memory_format import use_channels_last
from .state_dict_fit import RefuseMisfitMixin, refuse_misfit

__all__ = ['use_channels_last', 'refuse_misfit', 'RefuseMisfitMixin']
