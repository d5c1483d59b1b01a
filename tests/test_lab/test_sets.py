"""Experiment sets as data (cbnet_lab/sets.py): every shipped set file
reads, names configs that exist and build; malformed set files are clear
errors naming the file and what is wrong."""
import os.path as osp

import pytest

from cbnet_lab import recipe_comparison as rc
from cbnet_lab import sets
from cbnet_lab.config_edits import configs_root


def write(tmp_path, text, name='my_set'):
    path = tmp_path / f'{name}.py'
    path.write_text(text)
    return str(path)


GOOD_ROW = ("dict(name='stock', config='baselines/"
            "cascade-mask-rcnn_r18_fpn_1xb2-2k_cityscapes-like.py')")


def test_every_shipped_set_reads_and_its_configs_exist():
    found = sets.load_sets()
    assert {'ablation', 'realfog_pretrained', 'realfog_coco', 'coco_street',
            'fog_transfer'} <= set(found)
    presets = sets.load_presets()
    for name, spec in found.items():
        assert spec.name == name and spec.preset in presets
        assert spec.recipes, name
        for row in spec.recipes:
            path = osp.normpath(osp.join(configs_root(), row.config))
            assert osp.isfile(path), (name, row.name, path)
    # the harness's tables are these files, not a copy of them
    assert list(rc.RECIPE_SETS) == list(found)
    for name, spec in found.items():
        assert rc.RECIPE_SETS[name] == [(r.name, r.config)
                                        for r in spec.recipes]
        assert rc.SET_PRESETS.get(name, 'demo') == spec.preset


def test_the_realfog_coco_set_reads_as_declared():
    spec = sets.load_set('realfog_coco')
    assert spec.preset == 'realfog_coco'
    assert spec.recipe('YOLOX-Nano COCO, zero-shot').test_only
    assert spec.recipe('DCP + YOLOX-Nano COCO, zero-shot').test_only
    assert not spec.recipe('YOLOX-Nano COCO, fine-tuned').test_only
    longer = spec.recipe('YOLOX-Nano COCO, fine-tuned, 24 epochs')
    assert longer.budget == dict(iters_scale=2)
    assert longer.config == spec.recipe('YOLOX-Nano COCO, fine-tuned').config
    preset = sets.load_presets()['realfog_coco']
    # 12 epochs of the 152 training photos, in batches of 4
    assert preset.iters * preset.batch_size == 1800
    assert [c[0] for c in spec.columns] == [
        'box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
    with pytest.raises(KeyError, match='has no row'):
        spec.recipe('YOLOX-Nano, from nothing')


def test_row_budget_scales_the_sets_iterations():
    budget = rc.Budget(iters=450, batch_size=4, warmup_iters=50,
                       num_workers=0, img_scale=(640, 480))
    spec = sets.load_set('realfog_coco')
    longer = spec.recipe('YOLOX-Nano COCO, fine-tuned, 24 epochs')
    assert rc.row_budget(budget, longer).iters == 900
    # --iters moves every row alike
    assert rc.row_budget(rc.Budget(iters=2, batch_size=2, warmup_iters=1,
                                   num_workers=0), longer).iters == 4
    plain = spec.recipe('YOLOX-Nano COCO, fine-tuned')
    assert rc.row_budget(budget, plain) is budget
    assert rc.row_budget(budget, None) is budget
    fixed = sets.Recipe(name='x', config='y', budget=dict(batch_size=2))
    assert rc.row_budget(budget, fixed).batch_size == 2
    for bad in (0, -1, 'two', None.__class__):
        with pytest.raises(ValueError, match='iters_scale must be'):
            rc.row_budget(budget, sets.Recipe(
                name='x', config='y', budget=dict(iters_scale=bad)))
    with pytest.raises(ValueError, match='budget'):
        rc.row_budget(budget, sets.Recipe(name='x', config='y',
                                          budget=dict(epochs=3)))


def test_an_unknown_set_names_the_sets():
    with pytest.raises(KeyError, match="unknown recipe set 'nope'.*ablation"):
        sets.load_set('nope')


@pytest.mark.parametrize('text,match', [
    (f"recipes = [{GOOD_ROW}]\nprest = 'demo'\n", r"unknown keys \['prest'\]"),
    ("preset = 'demo'\n", 'recipes = .* is missing or empty'),
    ("recipes = []\n", 'missing or empty'),
    ("recipes = [dict(name='x')]\n", 'recipe 0 needs a name and a config'),
    ("recipes = [dict(config='a.py')]\n", 'needs a name and a config'),
    (f"recipes = [{GOOD_ROW}, dict(name='x', config='a.py', epochs=2)]\n",
     r"recipe 'x': unknown keys \['epochs'\]"),
    (f"recipes = [{GOOD_ROW}, {GOOD_ROW}]\n", "'stock' given twice"),
    (f"recipes = [dict(name='dcp', config='a.py', weights_of='stock'), "
     f"{GOOD_ROW}]\n", "weights of 'stock', which is no earlier row"),
    (f"recipes = [{GOOD_ROW}]\npreset = 'moon'\n", "unknown preset 'moon'"),
    (f"recipes = [{GOOD_ROW}]\ncolumns = ['box AP', 'box AP99']\n",
     'unknown column'),
    (f"recipes = [{GOOD_ROW}, dict(name='x', config='a.py', "
     "keep_img_scale='yes')]\n", 'keep_img_scale must be True or False'),
    (f"recipes = [{GOOD_ROW}]\ntransfer_test = dict(condition='fog')\n",
     "transfer_test needs a non-empty 'data_root'"),
    (f"recipes = [{GOOD_ROW}]\ntransfer_test = dict(condition='fog', "
     "data_root='d', seed=1)\n", r"transfer_test: unknown keys \['seed'\]"),
])
def test_malformed_set_files_are_clear_errors(tmp_path, text, match):
    path = write(tmp_path, text)
    with pytest.raises(ValueError, match=match) as err:
        sets.load_set('my_set', path)
    assert path in str(err.value)


def test_a_well_formed_file_reads(tmp_path):
    path = write(tmp_path, (
        f"preset = 'realfog_coco'\ncolumns = ['box AP', 'box AP50']\n"
        f"recipes = [{GOOD_ROW},\n"
        "    dict(name='dcp', config='a.py', weights_of='stock'),\n"
        "    dict(name='zs', config='b.py', test_only=True,\n"
        "         budget=dict(iters_scale=0.5))]\n"
        "transfer_test = dict(condition='fog', data_root='d')\n"))
    spec = sets.load_set('my_set', path)
    assert [r.name for r in spec.recipes] == ['stock', 'dcp', 'zs']
    assert spec.recipe('dcp').weights_of == 'stock'
    assert spec.recipe('zs').test_only and \
        spec.recipe('zs').budget == dict(iters_scale=0.5)
    assert not spec.recipe('zs').keep_img_scale
    assert sets.load_set('realfog_pretrained').recipe(
        'Edge FCOS-lite, 320 px').keep_img_scale
    assert spec.columns[1][0] == 'box AP50' and spec.file == path
    assert spec.transfer_test == dict(condition='fog', data_root='d')
    assert sets.load_set('fog_transfer').transfer_test['condition'] == \
        'real fog'


def test_real_data_is_named_by_its_folder():
    """The presets file's test_conditions: the condition a recipe written
    for a real-data folder is tested under, wherever its data is moved."""
    assert sets.TEST_CONDITIONS == sets.load_test_conditions() == dict(
        dawn_fog='real fog', coco_street='coco street')
    assert sets.data_condition('data/dawn_fog/') == 'real fog'
    assert sets.data_condition('/elsewhere/coco_street') == 'coco street'
    for root in ('data/cityscapes_like/', 'data/dawn_fog_val', None):
        assert sets.data_condition(root) is None


@pytest.mark.parametrize('spec,match', [
    ("dict(dawn_fog='')", 'non-empty name'),
    ("dict(dawn_fog='clear')", "other than the Cityscapes-layout data's"),
    ("{'data/dawn_fog': 'real fog'}", "must be a data folder's name"),
    ("dict(x='foggy beta=0.02')", 'Cityscapes-layout'),
])
def test_malformed_test_conditions_are_clear_errors(tmp_path, monkeypatch,
                                                    spec, match):
    (tmp_path / '_base_').mkdir()
    (tmp_path / '_base_' / 'presets.py').write_text(
        f'test_conditions = {spec}\n')
    monkeypatch.setattr(sets, 'experiments_dir', lambda: str(tmp_path))
    with pytest.raises(ValueError, match=match) as err:
        sets.load_test_conditions()
    assert 'presets.py: test_conditions' in str(err.value)


def test_a_malformed_presets_file_is_refused(tmp_path, monkeypatch):
    (tmp_path / '_base_').mkdir()
    (tmp_path / '_base_' / 'presets.py').write_text(
        "presets = dict(x=dict(data_root='d', iters=1))\n")
    monkeypatch.setattr(sets, 'experiments_dir', lambda: str(tmp_path))
    with pytest.raises(ValueError, match="preset 'x'"):
        sets.load_presets()
    (tmp_path / '_base_' / 'presets.py').write_text("presets = 3\n")
    with pytest.raises(ValueError, match='no presets'):
        sets.load_presets()
