"""tools/analysis_tools/profile_model.py on the demo config at 64x128."""
import importlib.util
import json
import os.path as osp

import pytest

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
SCRIPT = osp.join(ROOT, 'tools', 'analysis_tools', 'profile_model.py')
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')


@pytest.fixture(scope='module')
def tool():
    spec = importlib.util.spec_from_file_location('profile_model', SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_profile_infer_and_train(tool, tmp_path, capsys):
    out = tmp_path / 'profile.json'
    results = tool.main([
        DEMO, '--size', '64', '128', '--num-items', '3', '--warmup', '0',
        '--repeats', '1', '--top', '5', '--threads', '1', '--out',
        str(out)
    ])
    assert set(results) == {'infer', 'train'}
    infer, train = results['infer'], results['train']
    # every part of the detector got its own range, inside the whole call
    assert {'backbone', 'neck', 'rpn_head', 'roi_head'} <= set(
        infer['parts_ms'])
    assert {'loss_forward', 'backward', 'optimizer', 'backbone'} <= set(
        train['parts_ms'])
    for res in (infer, train):
        assert len(res['top_ops']) == 5
        selfs = [o['self_ms'] for o in res['top_ops']]
        assert selfs == sorted(selfs, reverse=True) and selfs[0] > 0
        assert 0 < sum(o['share'] for o in res['top_ops']) <= 1 + 1e-6
        assert res['wall_s'][0] > 0 and res['profiled_wall_s'] > 0
        # parts run inside the call: none takes longer than the call itself
        assert max(res['parts_ms'].values()) <= \
            res['profiled_wall_s'] * 1e3 * 1.05
    # the backward is a real part of a training step
    assert train['parts_ms']['backward'] > 0
    saved = json.loads(out.read_text())
    assert saved['meta']['machine']['threads'] == 1
    assert saved['results']['train']['top_ops'][0]['name']
    md = capsys.readouterr().out
    assert '### infer: median' in md and '### train: median' in md
    assert '| operator | calls | self CPU (ms) | share |' in md


def test_profile_cfg_options_reach_the_model(tool):
    """--cfg-options edits the config before the model is built."""
    args = tool.parse_args([
        DEMO, '--mode', 'train', '--cfg-options',
        'model.roi_head.mask_head.channels_last=False'
    ])
    assert args.cfg_options == {
        'model.roi_head.mask_head.channels_last': False
    }
    model, calls = tool.build(args)
    assert set(calls) == {'train'}
    assert model.roi_head.mask_head.channels_last is False
    default, _ = tool.build(tool.parse_args([DEMO, '--mode', 'infer']))
    assert default.roi_head.mask_head.channels_last is None


@pytest.mark.parametrize('argv, message', [
    (['missing.py'], 'config file not found'),
    ([DEMO, '--size', '16', '16'], 'too small'),
    ([DEMO, '--repeats', '0'], '--repeats must be positive'),
])
def test_profile_bad_arguments(tool, argv, message, capsys):
    with pytest.raises(SystemExit):
        tool.parse_args(argv)
    assert message in capsys.readouterr().err
