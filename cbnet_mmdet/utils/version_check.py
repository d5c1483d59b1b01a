"""Import-time check of the OpenMMLab stack against the declared ranges.

The ranges are declared once, in ``requirements/runtime.txt`` (read by
``pyproject.toml``); at import they are read back from the installed
distribution's metadata so the check can never drift from what pip enforced.
"""
from importlib import metadata
from typing import Dict, Optional

from packaging.requirements import Requirement
from packaging.version import Version

#: Distributions whose versions must be inside the declared ranges.
CHECKED = ('mmcv', 'mmdet', 'mmengine', 'setuptools')
#: Why a range matters, where the reason is not obvious.
WHY = {
    'setuptools': "MMEngine resolves our configs' `mmdet::` bases with "
    'pkg_resources, which setuptools 81 removed; pip install '
    '"setuptools<81"'
}


def declared_ranges(dist: str = 'cbnet_mmdet') -> Dict[str, Requirement]:
    """Requirements of ``dist`` for the checked packages, by name.

    Returns an empty dict when ``dist`` is not installed (a bare source tree
    on ``PYTHONPATH``): then nothing is checked.
    """
    try:
        requires = metadata.requires(dist) or []
    except metadata.PackageNotFoundError:
        return {}
    reqs = (Requirement(r) for r in requires)
    return {r.name: r for r in reqs if r.name in CHECKED and not r.marker}


def installed_version(name: str) -> Optional[str]:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def check_versions(ranges: Optional[Dict[str, Requirement]] = None,
                   versions: Optional[Dict[str, Optional[str]]] = None):
    """Raise ``ImportError`` naming every package outside its range.

    Args:
        ranges: requirement per package name; the installed metadata of
            ``cbnet_mmdet`` when None.
        versions: installed version per package name (None: missing); read
            from the environment when None.
    """
    ranges = declared_ranges() if ranges is None else ranges
    problems = []
    for name, req in sorted(ranges.items()):
        found = (versions[name] if versions is not None else
                 installed_version(name))
        if found is None:
            problems.append(f'{name} is not installed (need {req})')
        elif not req.specifier.contains(Version(found), prereleases=True):
            problems.append(f'{name}=={found} is installed, need {req}' +
                            (f' ({WHY[name]})' if name in WHY else ''))
    if problems:
        raise ImportError(
            'cbnet_mmdet cannot run with this OpenMMLab stack:\n  - ' +
            '\n  - '.join(problems) +
            '\nRun `bash tools/install.sh` (see README) to install the '
            'pinned stack.')
