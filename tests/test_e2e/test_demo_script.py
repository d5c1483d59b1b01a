"""End to end: the README's first command, ``bash tools/demo.sh``, at a
small size (8 train / 4 val images of the benchmark preset, one epoch):
every step runs through the user's path (install check, generator,
``mim train``, ``ap_drop.py``, ``draw_predictions.py``) and leaves what
docs/get_started.md says it leaves. How well the demo model learns is
``test_demo_learns.py``'s question; the full demo's figures are in
docs/get_started.md."""
import json
import os
import os.path as osp
import subprocess

import pytest
from mmengine.config import Config
from PIL import Image
from tool_helpers import load_tool

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
NUM_TRAIN, NUM_VAL = 8, 4


@pytest.mark.slow  # about 2 minutes on 2 cores
def test_demo_script_runs_every_step(tmp_path):
    work = tmp_path / 'demo'
    env = dict(os.environ, DEMO_NUM_TRAIN=str(NUM_TRAIN),
               DEMO_NUM_VAL=str(NUM_VAL), DEMO_EPOCHS='1',
               DEMO_WORK_DIR=str(work))
    run = subprocess.run(['bash', 'tools/demo.sh'], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=1200)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    for step in range(1, 6):
        assert f'] {step}/5 ' in run.stdout, step

    # the smaller set went to its own folder, never over the benchmark's
    data = osp.join(ROOT, 'data', f'cityscapes_like_bench_{NUM_TRAIN}-'
                    f'{NUM_VAL}')
    with open(osp.join(data, 'generator_record.json')) as f:
        record = json.load(f)
    assert [len(record['splits'][s]) for s in ('train', 'val')] == [
        NUM_TRAIN, NUM_VAL]
    assert record['img_size'] == [256, 512]  # the benchmark preset's
    # the run trained and tested on that folder, for the one epoch asked
    dumped = [p for p in os.listdir(work) if p.endswith('.py')]
    assert len(dumped) == 1, dumped
    cfg = Config.fromfile(str(work / dumped[0]))
    assert cfg.train_dataloader.dataset.dataset.data_root == data.replace(
        ROOT + '/', '') + '/'
    assert all(data.replace(ROOT + '/', '') in ev.ann_file
               for ev in cfg.test_evaluator)
    assert cfg.train_cfg.max_epochs == 1
    assert cfg.param_scheduler[1].end == 1
    assert (work / 'epoch_1.pth').is_file()

    # the printed table: clear and the two fog densities, numbers in %
    table = (work / 'ap_drop' / 'ap_drop.md').read_text()
    assert table in run.stdout
    rows = [line.split('|')[1:-1] for line in table.splitlines()[2:]]
    assert [r[0].strip() for r in rows] == [
        'clear', 'foggy beta=0.01', 'foggy beta=0.02']
    for r in rows:
        assert all(0.0 <= float(v) <= 100.0 for v in r[1:5]), r
    # the picture: 2 scenes x (clear | beta 0.01 | beta 0.02)
    title = load_tool('misc/draw_predictions.py').TITLE_HEIGHT
    with Image.open(work / 'predictions.png') as img:
        # panels at the data's size, each under its title band
        assert img.size == (3 * 512, 2 * (256 + title))
