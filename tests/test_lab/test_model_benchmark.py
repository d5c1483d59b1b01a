"""The model benchmark (cbnet_lab/model_benchmark.py): a checkpoint loads
strictly into its model, the scaling plot has a panel per measurement
(the command line over it: tests/test_tools/test_benchmark_cli.py)."""
import os.path as osp

import pytest
import torch
from tool_helpers import load_tool

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
#: the edge model of benchmark.py's --suite edge
EDGE = 'edge_fcos-lite_320'


def test_checkpoint_loads_strictly(tmp_path):
    from cbnet_lab.benchmark import build_detector
    from cbnet_lab.config_edits import load_benchmark_cfg
    from cbnet_lab.model_benchmark import Bench
    bench_script = load_tool('analysis_tools/benchmark.py')
    trained = build_detector(load_benchmark_cfg(
        osp.join(ROOT, bench_script.MODELS[EDGE])), seed=5).state_dict()
    torch.save(dict(state_dict=trained), tmp_path / 'edge.pth')
    args = bench_script.parse_args([
        '--suite', 'edge', '--models', EDGE, '--checkpoint', EDGE,
        str(tmp_path / 'edge.pth')])
    loaded = Bench(args).models[EDGE].state_dict()
    assert all(torch.equal(loaded[k], v) for k, v in trained.items())
    # a checkpoint of another model: an error, not a half-loaded model
    del trained['bbox_head.conv_cls.weight']
    torch.save(dict(state_dict=trained), tmp_path / 'other.pth')
    args = bench_script.parse_args([
        '--suite', 'edge', '--models', EDGE, '--checkpoint', EDGE,
        str(tmp_path / 'other.pth')])
    with pytest.raises(RuntimeError, match='conv_cls.weight'):
        Bench(args)


def test_scaling_plot_has_a_panel_per_measurement_only(tmp_path):
    """A run that timed only input sizes gets one panel (an empty
    'training vs instances' panel was drawn before); nothing measured is
    an error."""
    import cv2

    from cbnet_lab.model_benchmark import plot
    sizes = {'m': [dict(size=[64, 128], seconds=0.1),
                   dict(size=[128, 256], seconds=0.3)]}
    items = {'m': [dict(num_items=1, seconds=0.2),
                   dict(num_items=8, seconds=0.5)]}
    widths = {}
    for name, scaling in (('one', dict(sizes=sizes, items={})),
                          ('two', dict(sizes=sizes, items=items))):
        path = str(tmp_path / f'{name}.png')
        plot(scaling, path)
        widths[name] = cv2.imread(path).shape[1]
    assert widths == {'one': 500, 'two': 1000}  # 5 inches a panel, 100 dpi
    with pytest.raises(ValueError, match='no scaling measurement'):
        plot(dict(sizes={}, items={}), str(tmp_path / 'none.png'))
