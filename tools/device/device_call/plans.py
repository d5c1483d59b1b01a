"""The harness sets as the lent GPU machine runs them: every set file of
``configs/experiments/`` (read by ``cbnet_lab/sets.py``), nothing restated
here.

A set's plan, derived from its file, its preset and the presets file's
``device_data``:

- ``data``: its training data, the folder of its preset's ``data_root``
  under ``--data`` (carried), or made on the machine by the folder's
  ``make``; in a dry run without it, tiny data of its kind (``tiny``).
- ``transfer``: the folder of its preset's ``transfer_root`` (passed as
  --transfer-root), ``{folder}_val`` where only the val photos are tested
  (``val_only``: --prepare copies those and every XML).
- ``args``: the budget on the device, seeds 0 1 2 at the set's preset, so
  the device's runs merge with the CPU's records (--restore; a longer
  budget is a new table: add --iters N), ``--preset`` where the set's
  ``device`` names another; the dry run: 2 iterations of the set's
  ``dry_row`` for its ``dry_seeds`` at the data's ``dry_img_scale``.
- ``needs``: files its rows read (carried); ``tiny_weights``: the dry run's
  stand-ins of its pretrained files; ``weights_from``: the set whose rows
  some of its rows train as (``trained_as``), whose work dir is passed as
  --weights-from when that set ran earlier in the same call.
- ``runs``: recipes x seeds, one process each.

Reading the files needs the OpenMMLab stack, which a fresh device machine
has only after the set-up step: :func:`load_plans` reads them in the
project's interpreter (:func:`set_facts`), the rest is standard library.
"""
import glob
import json
import os.path as osp
import subprocess

from .runner import ROOT

#: The folder of the set files.
EXPERIMENTS = osp.join(ROOT, 'configs', 'experiments')
#: The seeds of a device run: the CPU records'.
SEEDS = ['0', '1', '2']
#: The dry run's budget: 2 iterations of 2 images, no worker processes.
DRY_BUDGET = ['--iters', '2', '--warmup-iters', '1', '--batch-size', '2',
              '--num-workers', '0']
DRY_CFG_OPTIONS = ['test_dataloader.num_workers=0',
                   'test_dataloader.persistent_workers=False']


def set_names():
    """The sets, one a file: every ``*.py`` directly under
    ``configs/experiments/`` (not ``_base_/``), as cbnet_lab/sets.py reads
    them."""
    return sorted(osp.splitext(osp.basename(p))[0]
                  for p in glob.glob(osp.join(EXPERIMENTS, '*.py')))


def set_facts(names) -> dict:
    """What each set's plan is made of (JSON), or its ``error`` where its
    file is malformed. Needs the OpenMMLab stack (cbnet_lab/sets.py)."""
    from dataclasses import asdict

    from cbnet_lab.sets import (data_folder, load_device_data, load_presets,
                                load_set)
    presets, data = load_presets(), load_device_data()

    def folder(root):
        return None if root is None else asdict(data[data_folder(root)])

    facts = {}
    for name in names:
        try:
            spec = load_set(name)
        except (KeyError, ValueError) as err:
            facts[name] = dict(error=str(err.args[0] if err.args else err))
            continue
        preset = presets[spec.device.preset]
        facts[name] = dict(
            preset=spec.device.preset, set_preset=spec.preset,
            data=folder(preset.data_root),
            transfer=folder(preset.transfer_root), rows=len(spec.recipes),
            device=asdict(spec.device),
            weights_from=(spec.trained_as or {}).get('set'))
    return facts


def read_facts(python, env, names) -> dict:
    """:func:`set_facts` in ``python`` (the project's interpreter, with
    the stack); each set's ``error`` if they could not be read."""
    code = ('import json, sys; sys.path.insert(0, sys.argv[1]); '
            'from device_call.plans import set_facts; '
            'print(json.dumps(set_facts(sys.argv[2:])))')
    try:
        out = subprocess.run(
            [python, '-c', code, osp.dirname(osp.dirname(__file__))] +
            list(names), env=env, cwd=ROOT, capture_output=True, text=True,
            timeout=300)
    except (OSError, subprocess.TimeoutExpired) as err:
        why = str(err)
    else:
        try:
            return json.loads(out.stdout.strip().splitlines()[-1])
        except (ValueError, IndexError):
            why = (out.stderr or out.stdout)[-1500:]
    return {n: dict(error=f'the set files could not be read: {why}')
            for n in names}


def plan(facts, dry) -> dict:
    """A set's plan (the module's docstring) from its :func:`set_facts`;
    the dry run's with ``dry``."""
    if 'error' in facts:
        return dict(error=facts['error'])
    data, transfer, device = facts['data'], facts['transfer'], \
        facts['device']
    if dry:
        seeds = [str(s) for s in device['dry_seeds']]
        row = device['dry_row']
        args = ['--seeds', *seeds] + DRY_BUDGET + (
            ['--only', row] if row is not None else []) + [
                '--img-scale', *map(str, data['dry_img_scale']),
                '--cfg-options', *DRY_CFG_OPTIONS]
        runs = (facts['rows'] if row is None else 1) * len(seeds)
    else:
        args, runs = ['--seeds', *SEEDS], facts['rows'] * len(SEEDS)
    if facts['preset'] != facts['set_preset']:
        args += ['--preset', facts['preset']]
    out = dict(data=data['name'], make=data['make'], tiny=data['tiny'],
               args=args, runs=runs, needs=[] if dry else device['needs'],
               tiny_weights=device['tiny_weights'],
               weights_from=facts['weights_from'], transfer=None)
    if transfer is not None:
        val = transfer['val_only']
        out.update(transfer=transfer['name'] + ('_val' if val else ''),
                   transfer_source=transfer['name'], val_only=val,
                   transfer_tiny=transfer['tiny'])
    return out


def load_plans(args, env, names) -> dict:
    """Set name -> :func:`plan` (``args.dry_run``'s), read by
    ``args.python`` in ``env``."""
    facts = read_facts(args.python, env, names)
    return {n: plan(facts.get(n, dict(error='not read')), args.dry_run)
            for n in names}
