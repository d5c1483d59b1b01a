"""The edge model exported to ONNX (cbnet_serving/export.py) and run on
ONNX Runtime (cbnet_serving/onnx_predictor.py): its detections must be
the PyTorch model's (DetInferencer), its in-graph priors MMDet's own grid,
and bad input a clear error. A YOLOX config of the repository with its own
random initialisation: no weights file, no shared data."""
import os.path as osp
from collections import OrderedDict

import numpy as np
import pytest
import torch

pytest.importorskip('onnx', reason='exporting needs onnx')
pytest.importorskip('onnxruntime', reason='running the export needs '
                    'onnxruntime (requirements/tests.txt installs it)')

from cbnet_serving import export as ex  # noqa: E402
from cbnet_serving.onnx_predictor import OnnxPredictor, letterbox  # noqa

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))
CONFIG = osp.join(ROOT, 'configs', 'yolox_coco',
                  'yolox_nano_coco-ft_1xb4-12e_dawn-fog.py')


@pytest.fixture(scope='module')
def checkpoint(tmp_path_factory):
    """A seeded random YOLOX-Nano of the config, saved as MMEngine saves
    one, with biases that make it detect (random heads keep no box past
    the score threshold otherwise)."""
    torch.manual_seed(0)
    detector, _, _ = ex.build_detector(CONFIG, None)
    with torch.no_grad():
        for conv in detector.bbox_head.multi_level_conv_obj:
            conv.bias.fill_(2.0)
        for conv in detector.bbox_head.multi_level_conv_cls:
            conv.bias.normal_(0, 2)
    path = str(tmp_path_factory.mktemp('ckpt') / 'yolox.pth')
    torch.save(dict(state_dict=detector.state_dict(), meta=dict(
        dataset_meta=dict(classes=[f'c{i}' for i in range(8)]))), path)
    return path


@pytest.fixture(scope='module')
def images():
    rng = np.random.default_rng(0)
    # a landscape frame, a portrait photo, an odd size: three paddings
    return [rng.integers(0, 256, s, dtype=np.uint8)
            for s in ((90, 160, 3), (150, 70, 3), (101, 203, 3))]


@pytest.fixture(scope='module')
def exported(checkpoint, tmp_path_factory):
    out = str(tmp_path_factory.mktemp('onnx') / 'edge.onnx')
    meta = ex.export_yolox(CONFIG, checkpoint, out)
    return out, meta


def test_the_exported_model_detects_what_pytorch_detects(
        exported, checkpoint, images):
    out, meta = exported
    assert meta['input_shape'] is None and meta['pad_size_divisor'] == 32
    assert meta['classes'] == [f'c{i}' for i in range(8)]  # the ckpt's
    gap = ex.detections_gap(out, CONFIG, checkpoint, images)
    rows = gap['images']
    assert gap['equal'], rows
    assert all(r['same_input'] for r in rows)
    assert all(r['torch_detections'] > 5 for r in rows)  # it detects
    assert max(r['max_box_gap'] for r in rows) < 1e-2
    assert max(r['max_score_gap'] for r in rows) < 1e-4


def test_in_graph_priors_are_mmdets_grid(checkpoint):
    detector, _, _ = ex.build_detector(CONFIG, checkpoint)
    graph = ex.YOLOXGraph(detector)
    gen = detector.bbox_head.prior_generator
    for h, w in ((64, 96), (96, 32)):
        feats = detector.extract_feat(torch.zeros(1, 3, h, w))
        want = torch.cat(gen.grid_priors([f.shape[-2:] for f in feats],
                                         device='cpu', with_stride=True))
        torch.testing.assert_close(graph.grid(feats), want)


def test_a_fixed_shape_pads_to_it_and_says_when_it_differs(
        checkpoint, images, tmp_path):
    out = str(tmp_path / 'fixed.onnx')
    meta = ex.export_yolox(CONFIG, checkpoint, out, shape=(384, 640))
    assert meta['input_shape'] == [384, 640]
    pred = OnnxPredictor(out, threads=1)
    batch, _, shrunk = letterbox(images[0], pred.meta)
    assert batch.shape == (1, 3, 384, 640) and not shrunk
    # 160x90 -> 640x360: the eager model pads to 640x384 too
    gap = ex.detections_gap(out, CONFIG, checkpoint, images[:1])
    assert gap['images'][0]['same_input'] and gap['equal']
    # a portrait photo resized to 221x480 does not fit 384 rows: shrunk
    _, _, shrunk = letterbox(images[1], pred.meta)
    assert shrunk
    with pytest.raises(ValueError, match='multiples of the largest'):
        ex.export_yolox(CONFIG, checkpoint, str(tmp_path / 'x.onnx'),
                        shape=(100, 640))


def test_bad_input_is_a_clear_error(exported, checkpoint, tmp_path):
    out, _ = exported
    pred = OnnxPredictor(out, threads=1)
    for bad in (np.zeros((8, 8), np.uint8), np.zeros((8, 8, 4), np.uint8)):
        with pytest.raises(ValueError, match='H x W x 3'):
            pred.predict([bad])
    with pytest.raises(FileNotFoundError, match='not found'):
        OnnxPredictor(str(tmp_path / 'missing.onnx'))
    junk = tmp_path / 'junk.onnx'
    junk.write_bytes(b'not a model')
    with pytest.raises(ValueError, match='not a model ONNX Runtime'):
        OnnxPredictor(str(junk))
    # a plain ONNX file without the exporter's metadata
    import onnx
    model = onnx.load(out)
    del model.metadata_props[:]
    plain = str(tmp_path / 'plain.onnx')
    onnx.save(model, plain)
    with pytest.raises(ValueError, match='export_onnx.py'):
        OnnxPredictor(plain)
    # not a YOLOX; a dehazer in front; a wrong checkpoint
    with pytest.raises(ValueError, match='takes an MMDet YOLOX'):
        ex.build_detector(osp.join(
            ROOT, 'configs', 'pretrained', 'fcos-lite_mobilenet-v2_fpn_'
            '1xb2-ft_dawn-fog-320.py'), None)
    with pytest.raises(ValueError, match='data preprocessor'):
        ex.build_detector(osp.join(
            ROOT, 'projects', 'peer_dehaze', 'configs', 'yolox_coco',
            'yolox_nano_coco-ft_dcp_1xb4-12e_dawn-fog.py'), None)
    wrong = str(tmp_path / 'wrong.pth')
    torch.save(dict(state_dict=OrderedDict(x=torch.zeros(1))), wrong)
    with pytest.raises(RuntimeError):
        ex.build_detector(CONFIG, wrong)


def test_route_and_speed_tools_run_the_export(exported, images, tmp_path,
                                              capsys):
    import cv2
    from tool_helpers import load_tool
    out, _ = exported
    frames = tmp_path / 'frames'
    frames.mkdir()
    for i, img in enumerate(images):
        cv2.imwrite(str(frames / f'{i}.png'), img)
    route = load_tool('projects/edge_serving/tools/route.py')
    route.main([out, '--input', str(frames), '--out-dir',
                str(tmp_path / 'local'), '--mode', 'local'])
    lines = (tmp_path / 'local' / 'results.jsonl').read_text().splitlines()
    assert len(lines) == 3
    want = OnnxPredictor(out, threads=1).predict(images[:1])[0]
    import json
    assert json.loads(lines[0])['prediction'] == want
    with pytest.raises(SystemExit):
        route.parse_args([out, 'x.pth', '--input', 'f', '--out-dir', 'o'])
    speed = load_tool('projects/edge_serving/tools/edge_speed.py')
    res = speed.main(['--model', 'onnx', out, '--model', 'eager', CONFIG,
                      '--repeats', '2', '--warmup', '0', '--size', '90',
                      '160', '--out-dir', str(tmp_path / 'speed')])
    assert set(res) == {'onnx', 'eager'}
    assert res['onnx']['input'] == res['eager']['input'] == [384, 640]
    assert len(res['onnx']['wall']) == 2 and res['onnx']['fps'] > 0
    assert (tmp_path / 'speed' / 'edge_speed.md').is_file()
    with pytest.raises(SystemExit):
        speed.parse_args(['--model', 'a', out, 'ckpt.pth', '--out-dir', 'o'])
    # a missing file: a usage error naming it, before anything loads
    missing = str(tmp_path / 'none.onnx')
    with pytest.raises(SystemExit) as err:
        speed.main(['--model', 'a', missing, '--out-dir', 'o'])
    assert err.value.code == 2
    assert f'--model a: no such file {missing}' in capsys.readouterr().err
    with pytest.raises(SystemExit) as err:
        speed.main(['--model', 'a', out, '--image', missing, '--out-dir',
                    'o'])
    assert f'--image {missing}: no such file' in capsys.readouterr().err


def test_export_tool_refuses_a_missing_check_image_before_exporting(
        tmp_path, capsys):
    """A --check image that does not exist is a usage error naming it,
    from main (so the documented command parses where the photo is not
    there) and before the export writes anything."""
    from tool_helpers import load_tool
    tool = load_tool('projects/edge_serving/tools/export_onnx.py')
    missing = str(tmp_path / 'none.jpg')
    out = tmp_path / 'edge.onnx'
    args = tool.parse_args([CONFIG, '--out', str(out), '--check', missing])
    assert args.check == [missing]
    with pytest.raises(SystemExit) as err:
        tool.main([CONFIG, '--out', str(out), '--check', missing])
    assert err.value.code == 2
    assert f'--check {missing}: no such file' in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(SystemExit):
        tool.parse_args([CONFIG, '--out', str(tmp_path / 'edge.txt')])
