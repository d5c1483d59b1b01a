import importlib.util
import json
import os.path as osp

from cbnet_tools.coco_statistics import coco_statistics, load_coco

TOOL = osp.join(osp.dirname(__file__), '..', '..', 'tools', 'misc',
                'dataset_stats.py')


def test_dataset_stats_cli(cityscapes_like_root, tmp_path, capsys):
    spec = importlib.util.spec_from_file_location('stats_tool', TOOL)
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    anns = [osp.join(cityscapes_like_root, 'annotations',
                     f'instancesonly_filtered_gtFine_{s}.json')
            for s in ('train', 'val')]
    out = str(tmp_path / 'stats.json')
    tool.main(anns + ['--json', out])
    text = capsys.readouterr().out
    with open(out) as f:
        written = json.load(f)
    for ann in anns:
        stats = coco_statistics(load_coco(ann))
        assert written[ann] == json.loads(json.dumps(stats))
        assert f'## {ann}' in text
        assert f'{stats["instances"]} instances' in text
    assert '| small |' in text and '| [8^2, 16^2) |' in text
