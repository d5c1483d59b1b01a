"""The YOLOX-Nano converter (cbnet_tools/yolox_weights.py, yolox_onnx.py)
and ``fetch_pretrained.py yolox_nano``, against an independent YOLOX in
Megvii's layout (yolox_reference.py, random weights and batch-norm
statistics): its state dict (the official key names) and its ONNX export
(batch norms folded, YOLOX's execution order), both converted to MMDet's
YOLOX-Nano, must compute what the reference computes. No network, no
shared files: the real ONNX file's check runs only where it is."""
import hashlib
import os
import os.path as osp

import pytest
import torch
from tool_helpers import load_tool
from yolox_reference import random_yolox

from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES
from cbnet_mmdet.utils.class_map import coco_classes
from cbnet_tools import pretrained as pt
from cbnet_tools import yolox_weights as yw

onnx = pytest.importorskip('onnx', reason='the ONNX side needs onnx '
                           '(requirements/tests.txt installs it)')
from cbnet_tools import yolox_onnx as yo  # noqa: E402

#: The shared copy of Megvii's ONNX export (../shared/weights), used where
#: it exists; CBNET_YOLOX_ONNX points elsewhere.
REAL_ONNX = os.environ.get('CBNET_YOLOX_ONNX', osp.join(
    osp.dirname(__file__), '..', '..', '..', 'shared', 'weights',
    'yolox_nano_coco.onnx'))
SIZE = 64  # the tests' input side (strides 8/16/32: 8x8, 4x4, 2x2 grids)


@pytest.fixture(scope='module')
def reference():
    return random_yolox(seed=0)


@pytest.fixture(scope='module')
def images():
    return torch.rand(2, 3, SIZE, SIZE,
                      generator=torch.Generator().manual_seed(1)) * 255


@pytest.fixture(scope='module')
def exported(reference, tmp_path_factory):
    """The reference exported to ONNX as Megvii's file was: eval mode,
    constants folded (batch norms into the convolutions), opset 11."""
    path = str(tmp_path_factory.mktemp('onnx') / 'yolox_nano.onnx')
    torch.onnx.export(reference, (torch.zeros(1, 3, SIZE, SIZE), ), path,
                      dynamo=False, opset_version=11,
                      input_names=['images'], output_names=['output'])
    return path


@pytest.fixture
def mmdet_nano():
    return yw.build_mmdet_yolox()


def converted(state_dict):
    model = yw.build_mmdet_yolox()
    pt.load_strictly(model, state_dict)
    return model


def test_the_table_names_every_tensor_of_mmdets_yolox_nano(mmdet_nano):
    rows = yw.conv_table()
    assert len(rows) == 113  # the ONNX file's Conv nodes
    pairs = yw._pairs(rows)
    assert sorted(m for _, m in pairs) == sorted(mmdet_nano.state_dict())
    # YOLOX's order: a CSPLayer's main branch first, the head's stems are
    # MMDet's neck.out_convs, level by level the class branch first
    assert rows[3][1:] == ('backbone.stage1.1.main_conv', 'convbn')
    assert rows[4][1:] == ('backbone.stage1.1.short_conv', 'convbn')
    head = rows[77:89]
    assert [m for _, m, _ in head][:6] == [
        'neck.out_convs.0',
        'bbox_head.multi_level_cls_convs.0.0.depthwise_conv',
        'bbox_head.multi_level_cls_convs.0.0.pointwise_conv',
        'bbox_head.multi_level_cls_convs.0.1.depthwise_conv',
        'bbox_head.multi_level_cls_convs.0.1.pointwise_conv',
        'bbox_head.multi_level_conv_cls.0']
    assert [m for _, m, _ in head][-2:] == [
        'bbox_head.multi_level_conv_reg.0', 'bbox_head.multi_level_conv_obj.0']


def test_official_weights_compute_what_yolox_computes(reference, images):
    state = reference.state_dict()
    assert 'backbone.backbone.dark2.1.conv1.bn.running_var' in state
    model = converted(yw.convert_official(state, yw.conv_table()))
    with torch.no_grad():
        want = reference(images)
    torch.testing.assert_close(yw.raw_outputs(model, images), want,
                               rtol=1e-4, atol=1e-4)
    # the official checkpoint wraps the weights ({'model': ...}); a DDP
    # save adds 'module.'
    ddp = {'module.' + k: v for k, v in state.items()}
    assert set(yw.official_state_dict({'model': ddp,
                                       'start_epoch': 300})) == set(state)


def test_official_weights_of_another_model_are_refused(reference):
    state = dict(reference.state_dict())
    rows = yw.conv_table()
    with pytest.raises(ValueError, match='1 of its tensors missing'):
        yw.convert_official(
            {k: v for k, v in state.items()
             if k != 'head.obj_preds.2.bias'}, rows)
    with pytest.raises(ValueError, match='1 unknown tensors'):
        yw.convert_official(dict(state, **{'head.extra.weight':
                                           torch.zeros(1)}), rows)
    # YOLOX-Tiny: no depthwise convolutions, other names and shapes
    tiny = random_yolox(seed=0, wid=0.375, depthwise=False).state_dict()
    with pytest.raises(ValueError, match='not the YOLOX this converter'):
        yw.convert_official(tiny, rows)
    # a YOLOX-Nano of other widths has the names: the strict load refuses
    wide = random_yolox(seed=0, wid=0.5).state_dict()
    with pytest.raises(ValueError, match='do not load strictly'):
        converted(yw.convert_official(wide, rows))
    for bad in (None, [], {'model': {}}):
        with pytest.raises(ValueError, match='not a YOLOX checkpoint'):
            yw.official_state_dict(bad)


def test_folded_onnx_computes_what_yolox_computes(reference, exported,
                                                  images, mmdet_nano):
    model = onnx.load(exported)
    ops = {n.op_type for n in model.graph.node}
    assert 'Conv' in ops and 'BatchNormalization' not in ops  # folded
    state = yo.convert_onnx(model, yw.conv_table(), mmdet_nano)
    bn = state['backbone.stage1.1.main_conv.bn.running_var']
    torch.testing.assert_close(bn, torch.full_like(bn, 1 - 1e-3))
    net = converted(state)
    with torch.no_grad():
        want = reference(images)
    torch.testing.assert_close(yw.raw_outputs(net, images), want,
                               rtol=1e-4, atol=1e-4)


def test_onnxruntime_agrees_where_installed(exported, mmdet_nano):
    pytest.importorskip('onnxruntime', reason='the output check needs '
                        'onnxruntime (an optional extra)')
    model = converted(yo.convert_onnx(onnx.load(exported), yw.conv_table(),
                                      mmdet_nano))
    assert yo.onnx_output_gap(exported, model) < 1e-4


def _swap_nodes(model, i, j):
    """Swap the i-th and j-th Conv nodes' weights and biases (their
    initializer names) in place."""
    convs = [n for n in model.graph.node if n.op_type == 'Conv']
    a, b = convs[i], convs[j]
    for k in (1, 2):
        a.input[k], b.input[k] = b.input[k], a.input[k]


def test_a_swapped_csp_branch_is_caught_by_the_graph_check(exported,
                                                           mmdet_nano):
    """main_conv and short_conv have equal shapes: only the graph tells
    them apart (main feeds the bottlenecks, short the concatenation)."""
    model = onnx.load(exported)
    rows = list(yw.conv_table())
    rows[3], rows[4] = rows[4], rows[3]  # a table that swapped them
    with pytest.raises(ValueError, match='CSPLayer branches are swapped'):
        yo.convert_onnx(model, rows, mmdet_nano)


def test_two_swapped_convolutions_change_the_outputs(reference, exported,
                                                     images, mmdet_nano):
    """Weights of two same-shape convolutions exchanged (the class and box
    branches' first depthwise convs of level 0): everything still loads,
    and the outputs no longer match the reference's (what the output
    check against the file catches)."""
    model = onnx.load(exported)
    rows = yw.conv_table()
    i = [r[1] for r in rows].index(
        'bbox_head.multi_level_cls_convs.0.0.depthwise_conv')
    j = [r[1] for r in rows].index(
        'bbox_head.multi_level_reg_convs.0.0.depthwise_conv')
    _swap_nodes(model, i, j)
    net = converted(yo.convert_onnx(model, rows, mmdet_nano))
    with torch.no_grad():
        gap = (yw.raw_outputs(net, images) - reference(images)).abs().max()
    # above what the command allows against the file (1e-3; a correct
    # conversion: about 1e-7 here)
    assert gap > yw.MAX_OUTPUT_GAP


def test_onnx_of_another_model_is_refused(tmp_path, mmdet_nano):
    other = random_yolox(seed=0, wid=0.375, depthwise=False)
    path = str(tmp_path / 'tiny.onnx')
    torch.onnx.export(other, (torch.zeros(1, 3, SIZE, SIZE), ), path,
                      dynamo=False, opset_version=11)
    with pytest.raises(ValueError, match='convolutions, the YOLOX this'):
        yo.convert_onnx(onnx.load(path), yw.conv_table(), mmdet_nano)
    wide = random_yolox(seed=0, wid=0.5)  # same graph, other widths
    torch.onnx.export(wide, (torch.zeros(1, 3, SIZE, SIZE), ), path,
                      dynamo=False, opset_version=11)
    with pytest.raises(ValueError, match='is not backbone.backbone.stem'):
        yo.convert_onnx(onnx.load(path), yw.conv_table(), mmdet_nano)
    junk = tmp_path / 'junk.onnx'
    junk.write_bytes(b'not a protobuf at all' * 10)
    with pytest.raises(ValueError, match='is not an ONNX model'):
        yo.load_onnx(str(junk))
    with pytest.raises(FileNotFoundError, match='not found'):
        yo.load_onnx(str(tmp_path / 'missing.onnx'))


def test_class_rows_start_from_cocos_classes_of_the_same_names(reference):
    state = yw.convert_official(reference.state_dict(), yw.conv_table())
    street = yw.map_class_rows(state, CITYSCAPES_CLASSES)
    coco = coco_classes()
    for level in range(3):
        key = f'bbox_head.multi_level_conv_cls.{level}.weight'
        assert street[key].shape[0] == 8
        for row, name in enumerate(CITYSCAPES_CLASSES):
            src = coco.index('person' if name == 'rider' else name)
            torch.testing.assert_close(street[key][row], state[key][src])
    # nothing else changes
    other = 'bbox_head.multi_level_conv_obj.1.bias'
    assert street[other] is state[other]
    with pytest.raises(ValueError, match=r"no source class stands for "
                       r"\['fog lamp'\]"):
        yw.map_class_rows(state, ('car', 'fog lamp'))
    with pytest.raises(ValueError, match='no classifier tensors'):
        yw.map_class_rows({'x': torch.zeros(80)}, ('car', ))


@pytest.mark.skipif(not osp.isfile(REAL_ONNX),
                    reason='the shared yolox_nano_coco.onnx is not here '
                    '(CI; CBNET_YOLOX_ONNX points at a copy)')
def test_the_real_onnx_file_converts_to_its_own_outputs(mmdet_nano):
    pytest.importorskip('onnxruntime', reason='needs onnxruntime')
    with open(REAL_ONNX, 'rb') as f:
        assert hashlib.sha256(f.read()).hexdigest() == yw.ONNX_SHA256
    model = converted(yo.convert_onnx(yo.load_onnx(REAL_ONNX),
                                      yw.conv_table(), mmdet_nano))
    assert yo.onnx_output_gap(REAL_ONNX, model) < 1e-4  # 2.1e-5 measured


# -- the command ---------------------------------------------------------

@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / 'cache'
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(folder))
    return folder


@pytest.fixture
def tool():
    return load_tool('model_converters/fetch_pretrained.py')


def _sha(path):
    with open(path, 'rb') as f:
        return hashlib.sha256(f.read()).hexdigest()


def test_fetch_from_onnx_writes_both_cache_files(tool, exported, cache,
                                                 monkeypatch, reference,
                                                 images):
    monkeypatch.setattr(yw, 'ONNX_SHA256', _sha(exported))
    out = tool.main(['yolox_nano', '--source', exported])
    assert out == pt.pretrained_path('yolox_nano')
    street = yw.street_path(out)
    assert osp.basename(street) in pt.DERIVED_FILES
    coco = torch.load(out, map_location='cpu', weights_only=True)
    assert coco['meta']['folded_batch_norms'] is True
    assert coco['meta']['sha256'] == _sha(exported)
    assert coco['meta']['dataset_meta']['classes'] == coco_classes()
    net = converted(coco['state_dict'])
    with torch.no_grad():
        torch.testing.assert_close(yw.raw_outputs(net, images),
                                   reference(images), rtol=1e-4, atol=1e-4)
    eight = torch.load(street, map_location='cpu', weights_only=True)
    assert eight['meta']['dataset_meta']['classes'] == CITYSCAPES_CLASSES
    assert 'rider <- person' in eight['meta']['class_map']
    model = yw.build_mmdet_yolox(num_classes=8)
    model.load_state_dict(eight['state_dict'], strict=True)
    assert not [f for f in os.listdir(cache) if f.endswith('.partial')]


def test_fetch_refuses_another_onnx_file_and_writes_nothing(
        tool, exported, cache):
    with pytest.raises(ValueError, match='sha256 .* expected 695e750a'):
        tool.main(['yolox_nano', '--source', exported])
    assert not cache.exists()


def test_fetch_from_the_official_pth(tool, reference, cache, tmp_path):
    pth = tmp_path / 'yolox_nano.pth'
    torch.save({'model': reference.state_dict(), 'start_epoch': 300}, pth)
    out = tool.main(['yolox_nano', '--source', str(pth)])
    ckpt = torch.load(out, map_location='cpu', weights_only=True)
    assert ckpt['meta']['folded_batch_norms'] is False
    torch.testing.assert_close(
        ckpt['state_dict']['neck.out_convs.1.bn.running_mean'],
        reference.head.stems[1].bn.running_mean)


def test_fetch_without_source_downloads_the_release_asset(
        reference, cache, tmp_path):
    saved = tmp_path / 'asset.pth'
    torch.save({'model': reference.state_dict()}, saved)
    calls = []

    def download(url, dst):
        calls.append(url)
        with open(saved, 'rb') as src, open(dst, 'wb') as out:
            out.write(src.read())

    coco, street = yw.fetch_yolox_nano(download=download, log=lambda m: 0)
    assert calls == [yw.OFFICIAL_URL]
    assert calls[0].endswith('/0.1.1rc0/yolox_nano.pth')
    assert osp.isfile(coco) and osp.isfile(street)


def test_fetch_bad_sources_are_clear_errors(tool, cache, tmp_path):
    with pytest.raises(FileNotFoundError, match='--source .* not found'):
        tool.main(['yolox_nano', '--source', str(tmp_path / 'none.pth')])
    text = tmp_path / 'notes.txt'
    text.write_text('hello')
    with pytest.raises(ValueError, match='neither an ONNX file'):
        tool.main(['yolox_nano', '--source', str(text)])
    other = tmp_path / 'other.pth'
    torch.save({'model': {'conv.weight': torch.zeros(1)}}, other)
    with pytest.raises(ValueError, match='not the YOLOX this converter'):
        tool.main(['yolox_nano', '--source', str(other)])
    assert not cache.exists()


def test_require_pretrained_names_the_command_for_load_from(cache):
    cfg = dict(model=dict(), load_from=osp.join(
        str(cache), 'yolox-nano_coco_megvii-0.1.1rc0_to-cityscapes-8.pth'))
    with pytest.raises(FileNotFoundError,
                       match='fetch_pretrained.py yolox_nano'):
        pt.require_pretrained(cfg)
    # a resumed run loads its own checkpoint; another name is MMEngine's
    pt.require_pretrained(dict(cfg, resume=True))
    pt.require_pretrained(dict(model=dict(), load_from='/no/such/run.pth'))


def test_list_shows_the_detector(tool, cache, capsys):
    tool.main(['--list'])
    out = capsys.readouterr().out
    assert 'yolox_nano: YOLOX-Nano (COCO' in out
    assert '_to-cityscapes-8.pth' in out
