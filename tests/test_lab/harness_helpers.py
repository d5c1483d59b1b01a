"""What the harness's tests share: a finished run's result as the harness
writes it (``fake_run``) and ``compare()`` with a stand-in in place of each
run (``stub_comparison``, ``fake_training``)."""
from cbnet_lab import plan
from cbnet_lab import recipe_comparison as rc
from cbnet_lab import run as lab_run
from cbnet_lab import summary


def fake_run(recipe, seed, clear, foggy, key='coco/segm_mAP'):
    return dict(recipe=recipe, seed=seed, train_time_s=10.0 + seed,
                metrics={'clear': {key: clear},
                         'foggy beta=0.02': {key: foggy}})


def stub_comparison(monkeypatch, run_recipe):
    """compare() with ``run_recipe`` in place of each run, no weights
    sources, clear val as reference, no pretrained files, no second test
    set and no plot."""
    monkeypatch.setattr(lab_run, 'run_recipe', run_recipe)
    monkeypatch.setattr(plan, 'weights_sources',
                        lambda recipes, *args, **kwargs: {
                            n: None for n, _ in recipes})
    monkeypatch.setattr(rc, 'reference_condition', lambda recipes: 'clear')
    monkeypatch.setattr(plan, 'check_pretrained', lambda *a: None)
    monkeypatch.setattr(plan, 'check_transfer', lambda *a: None)
    monkeypatch.setattr(summary, 'plot', lambda *a, **k: None)


def fake_training(tmp_path, monkeypatch, run_recipe):
    """:func:`stub_comparison` and a val file under ``tmp_path / 'data'``."""
    stub_comparison(monkeypatch, run_recipe)
    ann = tmp_path / 'data' / 'annotations'
    ann.mkdir(parents=True)
    (ann / 'instancesonly_filtered_gtFine_val.json').write_text('{}')
