"""Reading configs: the shipped ``configs`` folder and a parse cache.

Not an edit itself: every edit of :mod:`cbnet_lab.config_edits` starts
from :func:`read_config`'s copy of a file.
"""
import copy
import os
import os.path as osp
import re

from mmengine.config import Config


def configs_root() -> str:
    """The shipped ``configs`` folder (source tree or installed wheel)."""
    import cbnet_mmdet
    pkg = osp.dirname(osp.abspath(cbnet_mmdet.__file__))
    for root in (osp.join(osp.dirname(pkg), 'configs'),
                 osp.join(pkg, '.mim', 'configs')):
        if osp.isdir(root):
            return root
    raise FileNotFoundError(
        'cbnet_mmdet: no configs folder next to the package or in its '
        '.mim folder')


_READ_CONFIGS = {}
#: a ``{{$VAR:default}}`` of MMEngine's configs (its own pattern's start)
_ENV_REFERENCE = re.compile(r'''\{\{['\"]?\s*\$(\w+)\s*:''')


def read_config(path: str) -> Config:
    """``Config.fromfile(path)``, parsed once per process; a deep copy each
    call, so editing it changes nothing for the next caller.

    A comparison reads each recipe's config several times (its test
    condition, transfer set, trunk weights, the run's own config), and
    every ``mmdet::`` base in it makes MMEngine read all of MMDet's
    metafiles again (about a second each on the project's CPU). The parse
    is keyed by the file's real path, size and modification time, so a
    config rewritten in place is read again (its ``_base_`` files are
    assumed unchanged while the process runs), and it is checked against
    the environment variables that the config and its bases name in
    MMEngine's ``{{$VAR:default}}`` form (the pretrained recipes read
    ``CBNET_PRETRAINED_DIR``): one of those set, changed or unset since
    the parse reads the file again; any other variable changes nothing (a
    test runner sets one per test).

    The copy's text is not run through yapf: MMEngine formats a config's
    ``pretty_text`` with it each time a runner logs, dumps or checkpoints
    the config (4-6 times per lab run, about a second each for a cascade
    recipe on the project's CPU, half of a short test run). The text is
    the same Python, only its line breaks differ. ``Config.fromfile`` of
    MMEngine 0.10.7 drops its own ``format_python_code`` argument for a
    plain config, hence the explicit ``Config(...)`` here.
    """
    real = osp.realpath(path)
    if not osp.isfile(real):
        raise FileNotFoundError(f'config file not found: {path}')
    stat = os.stat(real)
    key = (real, stat.st_size, stat.st_mtime_ns)
    cached = _READ_CONFIGS.get(key)
    if cached is None or any(os.environ.get(name) != value
                             for name, value in cached[1].items()):
        cfg = Config.fromfile(path)
        cfg = Config(cfg.to_dict(), cfg_text=cfg.text, filename=cfg.filename,
                     env_variables=cfg.env_variables,
                     format_python_code=False)
        # cfg.text is the file's text after its bases' texts, as written
        read = {name: os.environ.get(name)
                for name in set(_ENV_REFERENCE.findall(cfg.text))}
        cached = _READ_CONFIGS[key] = (cfg, read)
    return copy.deepcopy(cached[0])
