import importlib.util
import json
import os.path as osp

TOOLS = osp.join(osp.dirname(__file__), '..', '..', 'tools')


def _tool(rel):
    spec = importlib.util.spec_from_file_location(
        osp.basename(rel)[:-3], osp.join(TOOLS, rel))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_converter_cli(cityscapes_like_root, tmp_path, capsys):
    tool = _tool('dataset_converters/cityscapes.py')
    out = tmp_path / 'ann'
    tool.main([cityscapes_like_root, '-o', str(out), '--splits', 'val',
               '--nproc', '2'])
    assert 'val:' in capsys.readouterr().out
    with open(out / 'instancesonly_filtered_gtFine_val.json') as f:
        ours = json.load(f)
    with open(osp.join(cityscapes_like_root, 'annotations',
                       'instancesonly_filtered_gtFine_val.json')) as f:
        assert json.load(f) == ours
    assert not (out / 'instancesonly_filtered_gtFine_train.json').exists()
