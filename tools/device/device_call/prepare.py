"""``--prepare``, here, not on the device: the wheels downloaded, each
set's data copied, the device tool's ``run`` call and its size."""
import json
import os
import os.path as osp
import shutil
import subprocess
import sys

from .plans import load_plans
from .runner import ROOT, python_env
from .stack import setup_plan


def prepare(args, wheels, mmcv) -> int:
    """Stage what a call carries (``wheels`` and the ``mmcv`` sdist into
    ``--wheels``, each set's data) and print the device tool's ``run``
    call with its size: the carried paths and the working tree must stay
    under 64 MiB together."""
    py = args.python
    os.makedirs(args.wheels, exist_ok=True)
    plat = ['--only-binary=:all:', '--python-version', '3.12',
            '--implementation', 'cp', '--platform', 'manylinux_2_28_x86_64',
            '--platform', 'manylinux_2_17_x86_64', '--platform',
            'manylinux2014_x86_64']
    if not setup_plan(args.wheels, wheels, mmcv)['items'] or args.refresh:
        subprocess.run([py, '-m', 'pip', 'download', '-q', '--no-deps',
                        '-d', args.wheels] + plat + wheels, check=True)
        # the sdist: its metadata step imports torch (this interpreter's)
        subprocess.run([py, '-m', 'pip', 'download', '-q', '--no-deps',
                        '--no-binary', ':all:', '--no-build-isolation',
                        '-d', args.wheels, mmcv], check=True)
    carry = [osp.relpath(args.wheels, ROOT)]
    plans = load_plans(args, python_env(args), args.sets)
    bad = {n: p['error'] for n, p in plans.items() if p.get('error')}
    if bad:
        print(f'malformed set files: {bad}', file=sys.stderr)
        return 1
    for name in args.sets:
        spec = plans[name]
        # the training data (unless the machine makes it) and the folder
        # the set is also tested on: (folder, its source, val_only)
        folders = [] if spec['make'] else [(spec['data'], spec['data'],
                                            None)]
        if spec['transfer']:
            folders.append((spec['transfer'], spec['transfer_source'],
                            spec['val_only']))
        for folder, source, val_only in folders:
            src = osp.join(args.data_src, source) if args.data_src \
                else None
            dst = osp.join(args.data, folder)
            if src and not osp.isdir(dst):
                if val_only:
                    copy_val_only(args.python, src, dst, *val_only)
                else:  # a link would travel as a link
                    shutil.copytree(src, dst)
            if osp.relpath(dst, ROOT) not in carry:
                carry.append(osp.relpath(dst, ROOT))
        carry += [p for p in spec['needs'] if p not in carry]
    if args.pretrained:
        carry.append(osp.relpath(args.pretrained, ROOT))
    sizes = {p: tree_bytes(osp.join(ROOT, p)) for p in carry}
    tracked = subprocess.run(
        ['git', 'ls-files', '-co', '--exclude-standard', '-z'], cwd=ROOT,
        capture_output=True, check=True).stdout.split(b'\0')
    tree = sum(osp.getsize(osp.join(ROOT, p.decode())) for p in tracked
               if p and osp.isfile(osp.join(ROOT, p.decode())))
    total = tree + sum(sizes.values())
    for p, b in [('(working tree)', tree)] + list(sizes.items()):
        print(f'{b / 2**20:8.1f} MiB  {p}')
    print(f'{total / 2**20:8.1f} MiB  total (the device tool takes 64)')
    cmd = ('bash tools/device/run_all.sh --out "$OUT"'
           + (f' --sets {" ".join(args.sets)}') +
           (f' --pretrained {osp.relpath(args.pretrained, ROOT)}'
            if args.pretrained else ''))
    print(json.dumps(dict(command=cmd, carry=carry, timeout_s=600),
                     indent=1))
    missing = [p for p in carry if not osp.exists(osp.join(ROOT, p))]
    if missing:
        print(f'missing, make them first: {missing}', file=sys.stderr)
    if total > 64 * 2**20 or len(carry) > 8:
        print('too much for one call: run the sets in separate calls '
              '(--sets)', file=sys.stderr)
        return 1
    return 1 if missing else 0


def copy_val_only(python, src, dst, val_fraction, seed):
    """Copy a VOC folder's ``Annotations/`` and the photos of the val
    subset of its seeded split (the dataset's own ``seeded_split``, run by
    the project's interpreter: this script imports nothing of it)."""
    code = ('import glob, os.path as osp, sys; from cbnet_mmdet.datasets.'
            'voc_fog import seeded_split; ids = [osp.basename(p)[:-4] for '
            'p in glob.glob(osp.join(sys.argv[1], "Annotations", "*.xml"))]'
            '; print("\\n".join(seeded_split(ids, "val", float(sys.argv[2]), '
            'int(sys.argv[3]))))')
    val = subprocess.run([python, '-c', code, src, str(val_fraction),
                          str(seed)], capture_output=True, text=True,
                         check=True).stdout.split()
    shutil.copytree(osp.join(src, 'Annotations'),
                    osp.join(dst, 'Annotations'))
    os.makedirs(osp.join(dst, 'JPEGImages'))
    photos = {osp.splitext(f)[0]: f for f in
              os.listdir(osp.join(src, 'JPEGImages'))}
    for i in val:
        shutil.copy2(osp.join(src, 'JPEGImages', photos[i]),
                     osp.join(dst, 'JPEGImages', photos[i]))
    return val


def tree_bytes(path) -> int:
    if osp.isfile(path):
        return osp.getsize(path)
    return sum(osp.getsize(osp.join(d, f)) for d, _, fs in os.walk(path)
               for f in fs)
