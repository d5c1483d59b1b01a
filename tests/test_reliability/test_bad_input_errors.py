"""Bad input reaches the user as one clear error naming the file or the
config key, raised by our code (not from deep inside mmcv/mmengine), when
training through ``tools/train.py`` with the demo config."""
import glob
import json
import os
import os.path as osp
import shutil

import pytest
import torch
from mmengine.logging import MMLogger
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401
from cbnet_tools.cityscapes_to_coco import convert
from tiny_configs import demo_cfg, load_tool, write_cfg

ANN = osp.join('annotations', 'instancesonly_filtered_gtFine_train.json')
# tools/train.py exports LOCAL_RANK (as launchers expect): undo it
pytestmark = pytest.mark.usefixtures('restore_environ')


def load_train_tool():
    return load_tool('train.py')


@pytest.fixture
def data_copy(cityscapes_like_root, tmp_path):
    """A copy of the tiny dataset (clear images, gtFine, annotations)."""
    root = str(tmp_path / 'data')
    shutil.copytree(
        cityscapes_like_root, root,
        ignore=shutil.ignore_patterns('leftImg8bit_foggy', 'depth'))
    return root


def first_image(root: str) -> str:
    return sorted(glob.glob(osp.join(
        root, 'leftImg8bit', 'train', '*', '*.png')))[0]


def train(root, tmp_path, *args):
    """Run ``tools/train.py``'s ``main`` on the shrunk demo config."""
    cfg = write_cfg(demo_cfg(root, max_epochs=1), str(tmp_path / 'cfg.py'))
    argv = [cfg, '--work-dir', str(tmp_path / 'work'), *args]
    load_train_tool().main(argv)


#: The package's own directory; a checkout or venv named ``cbnet_mmdet``
#: must not make every frame look like ours.
PACKAGE_DIR = osp.dirname(osp.abspath(cbnet_mmdet.__file__)) + os.sep


def raised_by_us(excinfo) -> bool:
    """The error was raised in the package's code, wrapping the library's."""
    return osp.abspath(str(excinfo.traceback[-1].path)).startswith(
        PACKAGE_DIR)


def break_missing_root(root):
    shutil.rmtree(root)
    return FileNotFoundError, osp.join(root, ANN)


def break_missing_image_folder(root):
    shutil.rmtree(osp.join(root, 'leftImg8bit'))
    return FileNotFoundError, osp.join(root, 'leftImg8bit', 'train')


def break_missing_image(root):
    path = first_image(root)
    os.remove(path)
    return FileNotFoundError, path


def break_invalid_json(root):
    with open(osp.join(root, ANN), 'a') as f:
        f.write('{ trailing garbage')
    return ValueError, osp.join(root, ANN)


def break_not_coco_json(root):
    with open(osp.join(root, ANN), 'w') as f:
        json.dump(dict(images=[dict(id=1)]), f)
    return ValueError, osp.join(root, ANN)


def break_truncated_image(root):
    path = first_image(root)
    with open(path, 'rb') as f:
        head = f.read(200)
    with open(path, 'wb') as f:
        f.write(head)
    return ValueError, path


def break_garbage_image(root):
    path = first_image(root)
    with open(path, 'wb') as f:
        f.write(b'not an image at all' * 10)
    return ValueError, path


@pytest.mark.parametrize('breaker', [
    break_missing_root, break_missing_image_folder, break_missing_image,
    break_invalid_json, break_not_coco_json, break_truncated_image,
    break_garbage_image
])
def test_broken_dataset_names_the_file(breaker, data_copy, tmp_path):
    exc_type, name = breaker(data_copy)
    with pytest.raises(exc_type) as excinfo:
        train(data_copy, tmp_path)
    assert name in str(excinfo.value)
    assert raised_by_us(excinfo), excinfo.traceback[-1]


def test_unknown_mit_arch_names_the_key(data_copy, tmp_path):
    with pytest.raises(ValueError, match=r"CBNetMiT: unknown arch 'b9'; "
                       r"valid names are \['b0', 'b1'"):
        train(data_copy, tmp_path, '--cfg-options', 'model.backbone.arch=b9')


def test_resume_from_missing_checkpoint(data_copy, tmp_path):
    missing = str(tmp_path / 'nope.pth')
    with pytest.raises(FileNotFoundError, match=f'--resume: .*{missing}'):
        train(data_copy, tmp_path, '--resume', missing)


def test_image_without_annotation_in_converter(data_copy):
    gt = sorted(glob.glob(osp.join(data_copy, 'gtFine', 'train', '*',
                                   '*_instanceIds.png')))[0]
    os.remove(gt)
    with pytest.raises(FileNotFoundError, match=osp.basename(gt)):
        convert(data_copy)


def test_checkpoint_that_does_not_fit_reports_what_did_not_load(
        cityscapes_like_root, tmp_path):
    cfg = demo_cfg(cityscapes_like_root, max_epochs=1)
    cfg.work_dir = str(tmp_path / 'work')
    runner = Runner.from_cfg(cfg)
    state = runner.model.state_dict()
    state.pop('roi_head.mask_head.conv_logits.weight')  # missing
    state['backbone.extra_layer.weight'] = torch.zeros(3)  # unexpected
    # (a mismatch in the backbone, neck or RPN head is refused outright:
    # tests/test_utils/test_checkpoint/test_checkpoint_fit.py)
    bias = 'roi_head.bbox_head.0.fc_cls.bias'
    model_shape = tuple(state[bias].shape)
    state[bias] = torch.zeros(1, 2, 3, 3)
    path = str(tmp_path / 'other.pth')
    torch.save(dict(state_dict=state, meta=dict()), path)
    runner._load_from = path
    runner.load_or_resume()
    with open(MMLogger.get_current_instance().handlers[-1].baseFilename) \
            as f:
        log = f.read()
    total = len(runner.model.state_dict())
    assert f'{total - 2} of {total} model tensors loaded from {path}' in log
    assert 'missing (1): roi_head.mask_head.conv_logits.weight' in log
    assert 'unexpected (1): backbone.extra_layer.weight' in log
    assert (f'mismatched (1): {bias}: checkpoint (1, 2, 3, 3) vs model '
            f'{model_shape}') in log
    # nothing fits: refuse instead of silently training from scratch
    torch.save(dict(state_dict=dict(fc=torch.zeros(2))), path)
    runner._has_loaded = False
    with pytest.raises(ValueError, match=f'no tensor of {path} fits'):
        runner.load_or_resume()
