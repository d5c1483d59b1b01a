"""tools/analysis_tools/proposal_quality.py: a run on the demo model, the
models and names asked for (the statistics are tested in
tests/test_lab/test_proposal_quality.py)."""
import json

import pytest
from tool_helpers import DEMO, demo_checkpoint, load_tool


@pytest.mark.slow  # builds and runs the demo model on 2 images
def test_demo_model_run(tmp_path, cityscapes_like_root):
    tool = load_tool('analysis_tools/proposal_quality.py')
    ckpt = demo_checkpoint(str(tmp_path / 'demo.pth'))
    out = tmp_path / 'p.json'
    tool.main([DEMO, ckpt, '--names', 'demo', '--data-root',
               cityscapes_like_root, '--max-images', '2', '--out', str(out)])
    r = json.loads(out.read_text())['results']['demo']
    assert r['images'] == 2 and r['gt_boxes'] > 0
    assert 0 < r['proposals_per_image'] <= 300  # the demo's test k
    assert 0 <= r['recall']['0.9'] <= r['recall']['0.5'] <= 1


def test_runs_are_read_from_training_folders(tmp_path):
    tool = load_tool('analysis_tools/proposal_quality.py')
    run = tmp_path / 'run'
    run.mkdir()
    (run / 'model.py').write_text('x = 1\n')
    ckpt = run / 'iter_600.pth'
    ckpt.write_bytes(b'')
    (run / 'last_checkpoint').write_text('/elsewhere/iter_600.pth')
    args = tool.parse_args(['--runs', str(run)])
    pairs = tool.models_of(args)
    assert pairs == [(str(run / 'model.py'), str(ckpt))]
    assert tool.default_names(args, pairs) == [f'{tmp_path.name}/run']
    (run / 'other.py').write_text('x = 2\n')
    with pytest.raises(SystemExit, match='one config'):
        tool.models_of(tool.parse_args(['--runs', str(run)]))


def test_bad_arguments(tmp_path):
    tool = load_tool('analysis_tools/proposal_quality.py')
    with pytest.raises(SystemExit):
        tool.main([])
    with pytest.raises(SystemExit):
        tool.main([DEMO])  # no checkpoint
    with pytest.raises(SystemExit, match='checkpoint not found'):
        tool.main([DEMO, str(tmp_path / 'missing.pth')])
    ckpt = tmp_path / 'c.pth'
    ckpt.write_bytes(b'')
    with pytest.raises(SystemExit, match='2 names for 1 models'):
        tool.main([DEMO, str(ckpt), '--names', 'a', 'b'])
    with pytest.raises(SystemExit, match='share a name'):
        tool.main([DEMO, str(ckpt), DEMO, str(ckpt)])
