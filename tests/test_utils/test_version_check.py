import pytest
from packaging.requirements import Requirement

from cbnet_mmdet.utils.version_check import check_versions, declared_ranges

RANGES = {
    'mmcv': Requirement('mmcv>=2.0.0,<2.2.0'),
    'mmdet': Requirement('mmdet>=3.3.0,<3.4.0'),
}


def test_inside_ranges_passes():
    check_versions(RANGES, {'mmcv': '2.1.0', 'mmdet': '3.3.0'})


def test_outside_range_names_every_offender():
    with pytest.raises(ImportError) as err:
        check_versions(RANGES, {'mmcv': '2.2.0', 'mmdet': '3.1.0'})
    msg = str(err.value)
    assert 'mmcv==2.2.0' in msg and 'mmcv<2.2.0,>=2.0.0' in msg
    assert 'mmdet==3.1.0' in msg
    assert 'tools/install.sh' in msg


def test_missing_package_is_reported():
    with pytest.raises(ImportError, match='mmdet is not installed'):
        check_versions(RANGES, {'mmcv': '2.1.0', 'mmdet': None})


def test_prerelease_inside_range_accepted():
    check_versions({'mmcv': Requirement('mmcv>=2.0.0rc4,<2.2.0')},
                   {'mmcv': '2.0.0rc4'})


def test_declared_ranges_come_from_installed_metadata():
    ranges = declared_ranges()
    # the installed cbnet_mmdet declares all four (requirements/runtime.txt)
    assert set(ranges) == {'mmcv', 'mmdet', 'mmengine', 'setuptools'}
    assert ranges['mmcv'].specifier.contains('2.1.0')
    assert not ranges['mmcv'].specifier.contains('2.2.0')
    # setuptools at run time: our configs' `mmdet::` bases need
    # pkg_resources, which setuptools 81 removed
    assert ranges['setuptools'].specifier.contains('80.10.2')
    assert not ranges['setuptools'].specifier.contains('81.0.0')


def test_setuptools_81_named_with_the_reason():
    ranges = declared_ranges()
    with pytest.raises(ImportError, match=r'setuptools==81.0.0 is installed'
                       r', need setuptools<81 \(.*pkg_resources'):
        check_versions(ranges, {'mmcv': '2.1.0', 'mmdet': '3.3.0',
                                'mmengine': '0.10.7',
                                'setuptools': '81.0.0'})


def test_unknown_distribution_checks_nothing():
    assert declared_ranges('no-such-distribution-xyz') == {}
