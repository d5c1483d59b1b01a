import json
import os

import pytest
# imported before any capsys: mmengine's progress bar binds sys.stdout as
# a default argument when it is first imported, and a test's capsys stream
# is closed after that test
import mmengine.utils.progressbar  # noqa: F401

from tool_helpers import load_tool


def test_generate_cli(tmp_path, capsys):
    tool = load_tool('misc/generate_cityscapes_like.py')
    root = tmp_path / 'cs'
    tool.main([str(root), '--num-train', '2', '--num-val', '1', '--size',
               '96', '192', '--seed', '1', '--betas', '0.01', '--convert',
               '--density', '0.5', '--min-height-px', '6'])
    out = capsys.readouterr().out
    assert 'train: 2 images' in out and 'val: 1 images' in out
    assert (root / 'leftImg8bit' / 'val' / 'frankfurt' /
            'frankfurt_000000_000019_leftImg8bit.png').is_file()
    assert (root / 'leftImg8bit_foggy' / 'val' / 'frankfurt' /
            'frankfurt_000000_000019_leftImg8bit_foggy_beta_0.01.png'
            ).is_file()
    with open(root / 'annotations' /
              'instancesonly_filtered_gtFine_train.json') as f:
        coco = json.load(f)
    assert len(coco['images']) == 2 and len(coco['annotations']) >= 16
    # COCO ids from 1 (pycocotools reads annotation id 0 as no match)
    assert min(a['id'] for a in coco['annotations']) == 1
    assert min(img['id'] for img in coco['images']) == 1
    with open(root / 'generator_record.json') as f:
        record = json.load(f)
    assert record['density'] == 0.5 and record['min_height_px'] == 6


def test_preset_fills_what_is_not_given():
    tool = load_tool('misc/generate_cityscapes_like.py')
    from cbnet_tools.synthetic.presets import DATA_PRESETS
    bench = DATA_PRESETS['bench']
    args = tool.parse_args(['out', '--preset', 'bench'])
    for key, value in bench.items():
        assert tuple(getattr(args, key)) == value if key == 'img_size' \
            else getattr(args, key) == value, key
    args = tool.parse_args(['out', '--preset', 'bench', '--num-train', '3',
                            '--size', '64', '128'])
    assert args.num_train == 3 and args.img_size == (64, 128)
    assert args.num_val == bench['num_val']
    # no preset: the generator's own defaults
    args = tool.parse_args(['out'])
    assert (args.num_train, args.num_val, tuple(args.img_size),
            args.min_height_px) == (40, 10, (256, 512), 8.0)


def test_reuse_keeps_the_same_dataset_and_refuses_another(tmp_path, capsys):
    tool = load_tool('misc/generate_cityscapes_like.py')
    root = tmp_path / 'cs'
    small = [str(root), '--num-train', '1', '--num-val', '1', '--size',
             '64', '128', '--betas', '0.01', '--convert', '--reuse']
    tool.main(small)
    assert 'train: 1 images' in capsys.readouterr().out
    png = root / 'leftImg8bit' / 'val' / 'frankfurt' / \
        'frankfurt_000000_000019_leftImg8bit.png'
    stamp = png.stat().st_mtime_ns
    # the same options: kept, nothing rewritten
    tool.main(small)
    assert 'already there' in capsys.readouterr().out
    assert png.stat().st_mtime_ns == stamp
    # converted annotations missing: only the conversion runs again
    ann = root / 'annotations' / 'instancesonly_filtered_gtFine_val.json'
    ann.unlink()
    tool.main(small)
    assert ann.is_file() and png.stat().st_mtime_ns == stamp
    # another dataset there: an error naming the difference, nothing lost
    with pytest.raises(SystemExit, match=r'num_train: 1 there, 2 asked'):
        tool.main([str(root), '--num-train', '2', '--num-val', '1', '--size',
                   '64', '128', '--betas', '0.01', '--reuse'])
    assert png.stat().st_mtime_ns == stamp
    # a folder with something else in it is not written into either
    other = tmp_path / 'other'
    other.mkdir()
    (other / 'keep.txt').write_text('x')
    with pytest.raises(SystemExit, match='no generator_record.json'):
        tool.main([str(other), '--num-train', '1', '--num-val', '1',
                   '--reuse'])
    assert os.listdir(other) == ['keep.txt']
