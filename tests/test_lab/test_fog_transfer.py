"""The fog_transfer set end to end on tiny files built here:
recipes trained on a tiny COCO-format clear set (through tools/
dataset_converters/coco_street.py), each tested on its clear val and on a
tiny VOC real-fog folder; the dehaze-then-detect rows (the dark channel
prior, the learned dehazer) train nothing and test the clear row's
checkpoint; the ceiling comes from a record."""
import json
import os
import os.path as osp
import shutil
from dataclasses import asdict

import pytest
import torch
from mmengine.config import Config
from mmengine.runner import Runner
from set_helpers import save_untrained_dehazer
from tool_helpers import FAST, TEST_IN_PROCESS, load_tool

from cbnet_lab import config_edits as ce
from cbnet_lab import plan
from cbnet_lab import recipe_comparison as rc
from cbnet_lab import run as lab_run
from cbnet_lab import set_conditions, summary

ROWS = [n for n, _ in rc.RECIPE_SETS['fog_transfer']]
#: test-only row -> the row whose checkpoint it tests
TEST_ONLY = {f'{dehazer} + {model}, clear (test only)': f'{model}, clear'
             for dehazer in ('DCP', 'dehazer')
             for model in ('Cascade Mask R-CNN', 'CBNet-PT')}
SCALE = ['--img-scale', '160', '96']


def ceiling_record(path, box_ap=(12.5, 8.0)):
    """A saved realfog_pretrained record with the two ceiling rows."""
    stat = lambda v: dict(mean=v, std=0.0, n=1)  # noqa: E731
    summary = {name: {'real fog': {'box AP': stat(ap),
                                   'box AP50': stat(2 * ap)}}
               for name, ap in zip(('Cascade R-CNN', 'CBNet-PT'),
                                   box_ap)}
    with open(path, 'w') as f:
        json.dump(dict(set='realfog_pretrained', seeds=[0],
                       date='2026-11-27 12:47 UTC', budget={},
                       summary=dict(conditions=['real fog'],
                                    summary=summary)), f)
    return str(path)


@pytest.mark.slow
def test_fog_transfer_set_end_to_end(street_and_fog, fake_weights,
                                     tmp_path, monkeypatch):
    street, fog = street_and_fog
    monkeypatch.chdir(tmp_path)  # the dehazer checkpoint path is relative
    dehazer_file = save_untrained_dehazer(tmp_path)
    trained, tested = [], []
    train, test = Runner.train, lab_run.ap_drop

    def spy_train(runner):
        trained.append(osp.relpath(runner.work_dir, tmp_path / 'runs'))
        return train(runner)

    def spy_test(cfgs):  # each run's test configs, by condition
        for condition, cfg in cfgs.items():
            tested.append((osp.relpath(cfg.work_dir, tmp_path / 'runs'),
                           osp.relpath(cfg.load_from, tmp_path / 'runs'),
                           condition, cfg.model.data_preprocessor.type))
        return test(cfgs)

    monkeypatch.setattr(Runner, 'train', spy_train)
    monkeypatch.setattr(lab_run, 'ap_drop', spy_test)
    tool = load_tool('analysis_tools/compare_recipes.py')
    argv = ['--set', 'fog_transfer', '--data-root', street,
            '--transfer-root', fog, '--work-dir', str(tmp_path / 'runs'),
            '--ceiling', ceiling_record(tmp_path / 'ceiling.json')] + \
        SCALE + FAST + ['--cfg-options'] + TEST_IN_PROCESS
    args = tool.parse_args(argv)
    assert args.preset == 'fog_transfer'  # the set's own preset
    record = tool.main(argv)

    # the trained rows trained once each; the test-only rows never
    slugs = {name: rc.slug(name) for name in ROWS}
    assert sorted(trained) == sorted(
        osp.join(slugs[n], 'seed0') for n in ROWS if n not in TEST_ONLY)
    runs = {r['recipe']: r for r in record['runs']}
    assert list(runs) == ROWS
    source_file = {row: osp.join(slugs[source], 'seed0', 'iter_2.pth')
                   for row, source in TEST_ONLY.items()}
    for row, source in TEST_ONLY.items():
        assert runs[row]['weights_of'] == source
        assert runs[row]['train_time_s'] is None
        weights = [f for f in os.listdir(tmp_path / 'runs' / slugs[row] /
                                         'seed0') if f.endswith('.pth')]
        if row.startswith('DCP + '):
            # the prior has no weights: the source's very checkpoint
            assert not weights and 'front_end_tensors' not in runs[row]
            tests = source_file[row]
        else:
            # the learned dehazer's weights (its own file) added to a copy
            # of the source's checkpoint, nothing else changed
            assert weights == ['front_end_iter_2.pth']
            tests = osp.join(slugs[row], 'seed0', weights[0])
            own = torch.load(dehazer_file)['state_dict']
            assert runs[row]['front_end_tensors'] == len(own)
            source_state = torch.load(tmp_path / 'runs' /
                                      source_file[row])['state_dict']
            composed = torch.load(tmp_path / 'runs' / tests)['state_dict']
            assert set(composed) == set(source_state) | {
                f'data_preprocessor.dehazer.{k}' for k in own}
            for k, v in composed.items():
                torch.testing.assert_close(
                    v, source_state[k] if k in source_state else
                    own[k[len('data_preprocessor.dehazer.'):]])
        # it tested those weights, behind its dehazer, on both sets
        mine = [t for t in tested if t[0].startswith(slugs[row] + '/')]
        assert [t[1:] for t in mine] == [
            (tests, condition, 'CBNetDehazeDataPreprocessor')
            for condition in ('coco street', 'real fog')]
    # every run: clear val of its training set, then DAWN-like real fog
    # through the VOC folder given, boxes only there
    for name, run in runs.items():
        assert list(run['metrics']) == ['coco street', 'real fog']
        assert 0.0 <= run['metrics']['real fog']['coco/bbox_mAP'] <= 1.0
        assert 'coco/segm_mAP' not in run['metrics']['real fog']
        assert 'coco/segm_mAP' in run['metrics']['coco street']
    assert sum(t[2] == 'real fog' for t in tested) == len(ROWS)
    summary = record['summary']
    assert summary['conditions'] == ['coco street', 'real fog']
    assert summary['columns'] == ['box AP', 'box AP50']
    for name, run in runs.items():
        entry = summary['summary'][name]
        clear = run['metrics']['coco street']['coco/bbox_mAP'] * 100
        foggy = run['metrics']['real fog']['coco/bbox_mAP'] * 100
        assert entry['real fog']['box AP drop']['mean'] == \
            pytest.approx(clear - foggy)
    assert record['transfer_root'] == fog
    # the ceiling: read from the record, beside the matching rows
    assert record['ceiling']['rows']['Cascade Mask R-CNN'] == dict(
        recipe='Cascade R-CNN', **{'box AP': dict(mean=12.5, std=0.0, n=1),
                                   'box AP50': dict(mean=25.0, std=0.0,
                                                    n=1)})
    md = (tmp_path / 'runs' / 'compare.md').read_text()
    assert '**real fog**' in md and '| box AP drop |' in md
    assert '**in-domain ceiling**' in md
    assert '| CBNet-PT (beside CBNet-PT) | 8.0 | 16.0 |' in md
    assert osp.isfile(tmp_path / 'runs' / 'compare.png')

    # a record restored elsewhere has the clear row's result but not its
    # weights: the test-only row says so, and nothing is trained
    trained.clear()
    clear_row, dcp_row = 'Cascade Mask R-CNN, clear', ROWS[3]
    restored = str(tmp_path / 'restored')
    os.makedirs(osp.dirname(rc.result_file(restored, clear_row, 0)))
    shutil.copy(rc.result_file(str(tmp_path / 'runs'), clear_row, 0),
                rc.result_file(restored, clear_row, 0))
    with pytest.raises(FileNotFoundError,
                       match=r"tests the weights of 'Cascade Mask R-CNN, "
                       r"clear', seed 0, .* not its weights"):
        tool.main(['--set', 'fog_transfer', '--only', clear_row, dcp_row,
                   '--data-root', street, '--transfer-root', fog,
                   '--work-dir', restored] + SCALE + FAST +
                  ['--cfg-options'] + TEST_IN_PROCESS)
    assert trained == []


@pytest.mark.slow
def test_generated_to_real_set_end_to_end(cityscapes_like_root, street_and_fog,
                                          fake_weights,
                                          tmp_path):
    """Item 3: trained on the generated scenes (clear, or their depth fog),
    tested on generated clear and foggy val, then on real fog."""
    _, fog = street_and_fog
    tool = load_tool('analysis_tools/compare_recipes.py')
    record = tool.main(
        ['--set', 'fog_generated_to_real', '--data-root',
         cityscapes_like_root, '--transfer-root', fog, '--betas', '0.02',
         '--work-dir', str(tmp_path / 'runs'), '--img-scale', '256', '128'] +
        FAST + ['--cfg-options'] + TEST_IN_PROCESS)
    names = [n for n, _ in rc.RECIPE_SETS['fog_generated_to_real']]
    assert [r['recipe'] for r in record['runs']] == names
    conditions = ['clear', 'foggy beta=0.02', 'real fog']
    for run in record['runs']:
        assert list(run['metrics']) == conditions
        assert 'coco/segm_mAP' not in run['metrics']['real fog']
    summary = record['summary']
    assert summary['conditions'] == conditions
    assert summary['columns'] == ['box AP', 'box AP50']
    assert 'box AP drop' in summary['summary'][names[1]]['real fog']
    assert 'ceiling' not in record
    md = (tmp_path / 'runs' / 'compare.md').read_text()
    assert '**foggy beta=0.02**' in md and '**real fog**' in md


def test_a_test_only_row_whose_source_never_ran_is_a_clear_error(
        tmp_path):
    clear, dcp = [(n, p) for n, p in rc.resolve_recipes('fog_transfer')
                  if n in ('Cascade Mask R-CNN, clear', ROWS[3])]
    budget = ce.Budget(iters=2)
    with pytest.raises(FileNotFoundError,
                       match="has not been trained in this work dir"):
        rc.run_recipe(dcp[0], dcp[1], 1, budget, str(tmp_path), [],
                      str(tmp_path), weights_of=clear[0])
    assert not osp.exists(
        rc.checkpoint_file(str(tmp_path), dcp[0], 1, budget))


def fake_runs(monkeypatch):
    """compare() with its runs, data checks and plot stubbed: the runs it
    asks for, as (name, seed, trained_in, weights_of)."""
    calls = []

    def fake_run_recipe(name, config, seed, *args, trained_in=None,
                        weights_of=None, **kwargs):
        calls.append((name, seed, trained_in, weights_of))
        return dict(recipe=name, seed=seed, train_time_s=None, metrics={
            'coco street': {'coco/bbox_mAP': 0.5},
            'real fog': {'coco/bbox_mAP': 0.2}})

    monkeypatch.setattr(lab_run, 'run_recipe', fake_run_recipe)
    monkeypatch.setattr(plan, 'check_pretrained', lambda *a: None)
    monkeypatch.setattr(plan, 'check_transfer', lambda *a: None)
    monkeypatch.setattr(summary, 'plot', lambda *a, **k: None)
    return calls


def test_transfer_test_is_checked(tmp_path):
    spec = dict(condition='real fog', data_root=str(tmp_path / 'missing'))
    cfg = Config(dict(test_dataloader=dict(dataset=dict(pipeline=[]))))
    cfg.filename = 'x.py'
    with pytest.raises(FileNotFoundError, match='--transfer-root'):
        ce.transfer_cfg(cfg, spec)
    assert ce.transfer_cfg(cfg, spec, str(tmp_path)).test_dataloader \
        .dataset.data_root == str(tmp_path)
    with pytest.raises(ValueError, match='named as a condition'):
        ce.ap_drop_cfgs(cfg, 'x.pth', str(tmp_path), [], 'real fog', spec,
                        str(tmp_path))
    # a set file's transfer_test, read
    for bad, match in (
            (dict(data_root='d'), "non-empty 'condition'"),
            (dict(condition='real fog'), "non-empty 'data_root'"),
            (dict(condition='real fog', data_root='d', splt='val'),
             r"unknown keys \['splt'\]"),
            ('real fog', 'must be dict')):
        with pytest.raises(ValueError, match=match) as err:
            set_conditions.transfer_test('my_set.py', bad)
        assert 'my_set.py: transfer_test' in str(err.value)
    assert set_conditions.transfer_test('my_set.py', None) is None


def transfer_jobs(set_name, budget=ce.Budget(iters=1)):
    """The runs of a set's first row, seed 0."""
    return plan.plan_jobs(rc.resolve_recipes(set_name)[:1], [0], budget,
                          'data', [], 'out', set_name=set_name)


def test_transfer_root_and_ceiling_errors(tmp_path):
    street, transfer = transfer_jobs('coco_street'), \
        transfer_jobs('fog_transfer')
    assert street[0].transfer_test is None
    assert transfer[0].transfer_test == \
        rc.SETS['fog_transfer'].transfer_test
    with pytest.raises(ValueError, match='have no second test set'):
        rc.check_transfer(street, str(tmp_path))
    with pytest.raises(FileNotFoundError, match='give it with'):
        rc.check_transfer(transfer, str(tmp_path / 'none'))
    rc.check_transfer(transfer, str(tmp_path))
    with pytest.raises(ValueError, match='also the name'):
        rc.check_transfer(transfer, str(tmp_path), 'real fog')
    other = tmp_path / 'other.json'
    other.write_text(json.dumps(dict(set='coco_street', summary={})))
    with pytest.raises(ValueError, match="not 'realfog_pretrained'"):
        rc.ceiling('fog_transfer', str(other), ['box AP'])
    with pytest.raises(ValueError, match='has no in-domain ceiling'):
        rc.ceiling('coco_street', str(other), ['box AP'])
    entry, md = rc.ceiling('fog_transfer', None, ['box AP'])
    assert entry is None and 'not tabulated' in md
    assert rc.ceiling('coco_street', None, ['box AP']) == (None, '')


def test_clear_rows_train_as_the_coco_street_rows_checked(tmp_path):
    recipes = rc.resolve_recipes('fog_transfer')
    assert rc.trained_as('fog_transfer', recipes) == {
        'Cascade Mask R-CNN, clear': 'Cascade Mask R-CNN',
        'CBNet-PT, clear': 'CBNet-PT'}
    with pytest.raises(ValueError, match='is for fog_transfer'):
        rc.trained_as('coco_street', recipes)
    # a config that trains otherwise (the fog augmentation) under the
    # clear row's name is refused, naming what differs
    aug = dict(recipes)['Cascade Mask R-CNN, clear + fog aug']
    with pytest.raises(ValueError, match=r"differ in \['train_dataloader'\]"):
        rc.trained_as('fog_transfer', [('Cascade Mask R-CNN, clear', aug)])


def finished_run(out, name, seed, budget, weights=True, **extra):
    """A finished run of another set's work dir: its result.json and,
    with ``weights``, its last checkpoint (a few bytes)."""
    path = rc.result_file(out, name, seed)
    os.makedirs(osp.dirname(path), exist_ok=True)
    with open(path, 'w') as f:
        json.dump(dict(recipe=name, seed=seed, budget=asdict(budget),
                       train_time_s=123.4, metrics={}, **extra), f)
    if weights:
        with open(rc.checkpoint_file(out, name, seed, budget), 'wb') as f:
            f.write(b'weights of ' + name.encode())
    return path


def test_find_trained(tmp_path):
    street, budget = str(tmp_path / 'street'), ce.Budget(iters=2)
    name = 'Cascade Mask R-CNN'
    with pytest.raises(FileNotFoundError, match='--weights-from'):
        rc.check_weights_from(street)
    path = finished_run(street, name, 0, budget)
    rc.check_weights_from(street)
    assert rc.find_trained(street, name, 0, budget) == path
    # restored from a record, without its weights: not usable here
    finished_run(street, name, 1, budget, weights=False)
    assert rc.find_trained(street, name, 1, budget) is None
    # never run, or not finished (and the other set's folder left as it
    # was)
    assert rc.find_trained(street, name, 2, budget) is None
    assert not osp.exists(osp.dirname(rc.result_file(street, name, 2)))
    # another budget, other overrides, other data: refused
    with pytest.raises(ValueError, match='another budget'):
        rc.find_trained(street, name, 0, ce.Budget(iters=3))
    with pytest.raises(ValueError, match='--cfg-options'):
        rc.find_trained(street, name, 0, budget, dict(a=1))
    with open(osp.join(street, 'compare.json'), 'w') as f:
        json.dump(dict(data_root=str(tmp_path / 'street_data')), f)
    rc.check_weights_from(street, str(tmp_path / 'street_data'))
    with pytest.raises(ValueError, match='not this data'):
        rc.check_weights_from(street, str(tmp_path))


def test_a_run_trained_elsewhere_is_tested_not_trained(
        tmp_path, monkeypatch):
    street, out = str(tmp_path / 'street'), str(tmp_path / 'runs')
    budget = ce.Budget(iters=2)
    source = finished_run(street, 'Cascade Mask R-CNN', 0, budget,
                          resumed_at_iter=1, train_time_extrapolated=True)
    tested = []

    def fake_ap_drop_cfgs(cfg, checkpoint, work_dir, betas, **kwargs):
        return {'coco street': checkpoint}

    def fake_ap_drop(cfgs):
        tested.extend(cfgs.values())
        return dict(metrics={'coco street': {'coco/bbox_mAP': 0.5}})

    def no_training(*args, **kwargs):
        raise AssertionError('nothing may be trained')

    monkeypatch.setattr(lab_run, 'ap_drop_cfgs', fake_ap_drop_cfgs)
    monkeypatch.setattr(lab_run, 'ap_drop', fake_ap_drop)
    monkeypatch.setattr(Runner, 'from_cfg', no_training)
    name, config = rc.resolve_recipes('fog_transfer')[0]
    result = rc.run_recipe(name, config, 0, budget, str(tmp_path), [], out,
                           trained_in=source)
    mine = rc.checkpoint_file(out, name, 0, budget)
    # the very file the coco_street run saved, tested under this config
    assert osp.samefile(mine, rc.checkpoint_file(
        street, 'Cascade Mask R-CNN', 0, budget))
    assert tested == [mine]
    assert result['train_time_s'] == 123.4
    assert result['trained_in'] == osp.dirname(source)
    assert result['trained_as'] == 'Cascade Mask R-CNN'
    assert result['resumed_at_iter'] == 1
    assert result['train_time_extrapolated'] is True
    with open(rc.result_file(out, name, 0)) as f:
        assert json.load(f) == result


def test_compare_takes_what_the_other_set_trained(tmp_path, monkeypatch):
    """Seed 0 finished there (tested here, the DCP row then tests the same
    weights), seed 1 never run there (trained here), the test-only row
    after the clear row of the same seed."""
    street, out = str(tmp_path / 'street'), str(tmp_path / 'runs')
    budget = ce.Budget(iters=2)
    recipes = [r for r in rc.resolve_recipes('fog_transfer')
               if r[0] in ('Cascade Mask R-CNN, clear', ROWS[3])]
    source = finished_run(street, 'Cascade Mask R-CNN', 0, budget)
    calls = fake_runs(monkeypatch)
    logs = []
    record = rc.compare(recipes, [0, 1], budget, str(tmp_path), [], out,
                        log=logs.append, set_name='fog_transfer',
                        weights_from=street)
    clear, dcp = recipes[0][0], recipes[1][0]
    assert calls == [(clear, 0, source, None), (dcp, 0, None, clear),
                     (clear, 1, None, None), (dcp, 1, None, clear)]
    assert [(r['recipe'], r['seed']) for r in record['runs']] == [
        (clear, 0), (dcp, 0), (clear, 1), (dcp, 1)]
    assert record['weights_from'] == street
    said = '\n'.join(logs)
    assert f'testing the weights trained in {osp.dirname(source)}' in said
    assert "training (no finished run of 'Cascade Mask R-CNN'" in said
    # a set none of whose rows train as another's: --weights-from refused
    with pytest.raises(ValueError, match='is for fog_transfer'):
        rc.compare(rc.resolve_recipes('coco_street')[:1], [0], budget,
                   str(tmp_path), [], str(tmp_path / 'x'),
                   set_name='coco_street', weights_from=street)
