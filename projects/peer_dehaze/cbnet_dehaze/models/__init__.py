from .data_preprocessors import *  # noqa: F401,F403
from .dehazers import *  # noqa: F401,F403
from .losses import *  # noqa: F401,F403
