"""Train recipes on the same data, budget and seeds; compare them.

Every recipe (an MMDet config) is trained ``--iters`` iterations of
``--batch-size`` images with a linear warm-up and a poly decay, once per
seed, then tested on clear val and on foggy val for each ``--betas``.
Output in ``--work-dir``: ``compare.json`` (every run and the summary),
``compare.md`` (mean +- std over seeds: AP/mIoU or AR per condition, the
drop from clear to each fog density, training time) and ``compare.png``
(the main metric vs fog density per recipe). Finished runs are kept: a
rerun (after a kill, or with more seeds) only trains what is missing.

A test-time variant is not trained: it tests the weights another recipe
trained for each seed (list that recipe first) under its own test
settings; a set's rows say it with ``weights_of`` in the set file,
``--configs`` recipes with ``--weights-of NAME=SOURCE``.

Built-in sets (configs under configs/, the dehazer + detector ones under
projects/peer_dehaze/configs/; demo-size, one MiT-B0 trunk):
  arch      CBNet vs MMDet's stock Cascade Mask R-CNN and Mask R-CNN
  ablation  the four rows of the paper's Table 3 (trained on foggy images)
  dehaze    CBNet on fog vs dehazer + detector (train the dehazer first:
            projects/peer_dehaze/README.md)
  speed     the speed settings (docs/benchmarks.md): light neck, 3 / 7 stacks,
            1000 proposals at test (a test-time variant)
  rpn       CBNet's Cascade RPN vs RPNHead vs MMDet's CascadeRPNHead
  parts     what each part of CBNet is worth: MMDet's stock Cascade Mask
            R-CNN with ONE CBNet part swapped in, and CBNet with ONE part
            taken back (configs/demo/parts/); --only picks rows
  realfog   box-only recipes on real fog (a VOC folder: DAWN, RTTS):
            CBNet's box path, Cascade R-CNN and YOLOX-Tiny learning on
            fog vs the last two behind the dark channel prior or the
            learned dehazer; tested on the folder's val split, no betas
  coco_street  real photographs with masks (the COCO street subset,
            converted by tools/dataset_converters/coco_street.py) on an
            ImageNet MobileNetV2 (tools/model_converters/
            fetch_pretrained.py mobilenet_v2): MMDet's Cascade Mask
            R-CNN, the paper's CBNet, the revised CBNet, the revised one
            with RPNHead, CBNet-PT (the revised one with FPN for NAS-FPN,
            the CBNet for pretrained trunks); mask AP, box AP, mIoU
  realfog_pretrained  the same recipes box-only on DAWN's fog and haze
            at 640 px on the same trunk, plus YOLOX-Tiny (from scratch)
            and the dark channel prior in front of the Cascade R-CNN;
            box AP, AP50, AP_s/m/l
  realfog_pretrained_parts  the stock Cascade R-CNN and the revised
            CBNet's box path at the full trunk lr (the two rows of
            realfog_pretrained_finetune), each with ONE of the parts in
            which they differ (neck, RPN, stage IoUs) taken from the
            other (configs/pretrained/parts/); the same preset and
            columns
  realfog_pretrained_finetune  the same two recipes with the trunk at
            the full lr (lr_mult 1) instead of a tenth
            (configs/pretrained/finetune/); the same preset and columns,
            the two recipes' runs reused from a realfog_pretrained
            work dir
  realfog_pretrained_trunks  the stock Cascade R-CNN and the revised
            CBNet at the full trunk lr on MobileNetV2 and on an ImageNet
            EfficientNet-Lite0
            (CBNetEfficientNetLite; weights: fetch_pretrained.py
            efficientnet_lite0); the same preset and columns
  realfog_pretrained_neck  the revised CBNet at the full trunk lr with
            NAS-FPN on BatchNorm (batches of 2), with FPN, and with
            NAS-FPN on GroupNorm (configs/pretrained/neck/); the same
            preset and columns, the first two rows reused from the parts
            set's work dir
  fog_transfer  does synthetic fog carry over to real fog? The stock
            cascade and CBNet-PT trained on the CLEAR COCO street
            photos: clear only, + CBNetAddFog augmentation, CBNet-DD on
            synthetic foggy twins, and the dark channel prior in front of
            the clear-only checkpoint at test time (trains nothing); each
            tested on COCO street val and on DAWN's fog + haze val
            (--transfer-root), box AP / AP50 and the drop; --ceiling adds
            the realfog_pretrained record (trained on DAWN) as the ceiling;
            the clear-only rows train exactly as the coco_street set's
            two rows: --weights-from that set's work dir tests its
            finished runs instead of training them again
  fog_generated_to_real  the same two models trained on the generated
            scenes (bench preset), clear or with their depth-rendered fog
            (beta 0.02), tested on generated clear / foggy val and on
            DAWN's real fog (--transfer-root): rendered fog vs real fog

Presets (--preset): `demo` (the default: 128x256 data, 120 iterations of
4 images, every recipe at 1-5 AP) and `bench` (the benchmark: 256x512
data from `generate_cityscapes_like.py --preset bench`, a budget where
recipes can be told apart; docs/accuracy.md); `coco_street` and
`realfog_pretrained` (photos at most 640x480, batches of 2, the budgets
of docs/accuracy.md "Real masks" and docs/robustness.md "Real fog on a
pretrained trunk") are the default of the set of the same name, as is
`fog_transfer` (the coco_street budget, DAWN as the second test set).

Where the runs run (recipe x seed, each in its own folder): one after
another in this process (the default); --jobs N: N worker processes on
this machine (e.g. one per core with --threads 1, or several runs on one
GPU); --executor ray: each run a Ray task with --run-cpus / --run-gpus of
its own, on the Ray cluster at --address or on a local Ray (--jobs N: N
runs at once). A test-time variant runs after the run whose weights it
tests. The comparison's record is the same whichever runs them. A run
saves a checkpoint every sixth of its iterations; a sweep killed mid-way
goes on when the same command is started again: finished runs are read
back, a run cut short resumes from its checkpoint (its record says
``resumed_at_iter``). Start one command per work dir (it runs every run
of it itself; --no-wait and the runs' lock files are gone).

Recipes written for real data (a config whose data_root is a folder of
``test_conditions`` in configs/experiments/_base_/presets.py, which names
its condition: DAWN's real fog, like the realfog set, or COCO street) take
``--data-root`` as their data (default: the config's) and are tested on
their own test set only: no ``--betas``.

Examples::

    python tools/misc/generate_cityscapes_like.py data/cityscapes_like \
        --convert
    OMP_NUM_THREADS=1 python tools/analysis_tools/compare_recipes.py \
        --set arch --seeds 0 1 2 --iters 120
    # the benchmark: data once, then the parts set, two runs at once
    python tools/misc/generate_cityscapes_like.py \
        data/cityscapes_like_bench --preset bench --nproc 2 --convert
    OMP_NUM_THREADS=1 python tools/analysis_tools/compare_recipes.py \
        --set parts --preset bench --threads 1 --jobs 2
    # the same on a Ray cluster, a GPU for each run
    python tools/analysis_tools/compare_recipes.py --set parts \
        --preset bench --executor ray --address auto --run-gpus 1
    # your own configs, on the real data
    python tools/analysis_tools/compare_recipes.py \
        --configs mine=configs/my.py baseline=configs/base.py \
        --data-root data/cityscapes --iters 2000 --batch-size 8
    # real fog: DAWN's fog/haze photos (docs/robustness.md, "Real fog")
    OMP_NUM_THREADS=1 python tools/analysis_tools/compare_recipes.py \
        --set realfog --data-root data/dawn_fog --threads 1
    # pretrained trunk: weights once, then real fog and real masks
    python tools/model_converters/fetch_pretrained.py mobilenet_v2
    OMP_NUM_THREADS=1 python tools/analysis_tools/compare_recipes.py \
        --set realfog_pretrained --data-root data/dawn_fog --threads 1
    python tools/dataset_converters/coco_street.py COCO_SUBSET \
        data/coco_street
    OMP_NUM_THREADS=1 python tools/analysis_tools/compare_recipes.py \
        --set coco_street --data-root data/coco_street --threads 1
    # synthetic fog to real fog: train on clear COCO street, test on both
    OMP_NUM_THREADS=1 python tools/analysis_tools/compare_recipes.py \
        --set fog_transfer --data-root data/coco_street \
        --transfer-root data/dawn_fog --threads 1 \
        --ceiling work_dirs/compare/realfog_pretrained/compare.json \
        --weights-from work_dirs/compare/coco_street
    # generated -> real: the bench data once, then the set
    python tools/misc/generate_cityscapes_like.py \
        data/cityscapes_like_bench --preset bench --nproc 2 --convert
    OMP_NUM_THREADS=1 python tools/analysis_tools/compare_recipes.py \
        --set fog_generated_to_real --transfer-root data/dawn_fog \
        --threads 1
"""
import argparse
import sys

from mmengine.config import DictAction


class Removed(argparse.Action):
    """An option that is no more: its use is an error saying why."""

    def __init__(self, option_strings, dest, why='', **kwargs):
        self.why = why
        super().__init__(option_strings, dest, nargs=0,
                         help=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        parser.error(f'{option_string} was removed: {self.why}')


def parse_args(argv=None):
    from cbnet_lab.recipe_comparison import (PRESETS, RECIPE_SETS,
                                             SET_PRESETS)
    parser = argparse.ArgumentParser(
        description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split('\n\n', 1)[1])
    parser.add_argument('--set', choices=sorted(RECIPE_SETS),
                        help='a built-in set of recipes')
    parser.add_argument('--configs', nargs='+', default=[],
                        metavar='[NAME=]CONFIG',
                        help='recipes to compare (added after --set)')
    parser.add_argument('--only', nargs='+', metavar='NAME',
                        help='run only these recipes of the set/configs')
    parser.add_argument('--preset', choices=sorted(PRESETS),
                        help='data root, budget and image size to start '
                        'from (the options below override it; default: '
                        "the set's own (" + ', '.join(
                            f'{k}: {v}' for k, v in sorted(
                                SET_PRESETS.items())) + '), else demo): ' +
                        '; '.join(f'{k}: {v.describe()}'
                                  for k, v in sorted(PRESETS.items())))
    parser.add_argument('--data-root',
                        help='dataset in the Cityscapes layout with '
                        'converted annotations and leftImg8bit_foggy '
                        "(default: the preset's); for real-data recipes "
                        "their data (default: the config's)")
    parser.add_argument('--transfer-root',
                        help="the real-fog VOC folder of the set's second "
                        "test set (its file's transfer_test; default: the "
                        "preset's, else the set file's)")
    parser.add_argument('--ceiling', metavar='COMPARE_JSON',
                        help="the in-domain ceiling's record, tabulated "
                        'under the results, never retrained (fog_transfer: '
                        "the realfog_pretrained set's compare.json)")
    parser.add_argument('--weights-from', metavar='WORK_DIR',
                        help='the work dir of the set whose rows some of '
                        "this set's rows train exactly as (fog_transfer: "
                        "the coco_street set's, for the clear-only rows): "
                        'its finished runs (same budget and data) are '
                        'tested here, not trained again')
    parser.add_argument('--weights-of', nargs='+', default=[],
                        metavar='NAME=SOURCE',
                        help='test-time variants among --configs: recipe '
                        'NAME trains nothing and tests the weights that '
                        'recipe SOURCE (listed before it) trained, seed by '
                        "seed (a set's rows: weights_of in its file)")
    parser.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2])
    parser.add_argument('--iters', type=int,
                        help='training iterations per run (0: untrained)')
    parser.add_argument('--batch-size', type=int)
    parser.add_argument('--lr', type=float, default=None,
                        help="base lr (default: each config's)")
    parser.add_argument('--warmup-iters', type=int)
    parser.add_argument('--img-scale', type=int, nargs=2,
                        metavar=('W', 'H'),
                        help='scale of every Resize in the pipelines '
                        "(default: the preset's; the demo preset keeps "
                        "each config's)")
    parser.add_argument('--num-workers', type=int, default=1)
    parser.add_argument('--betas', type=float, nargs='*', default=None,
                        help='fog densities (1/m) to test on (default '
                        '0.005 0.01 0.02; none for real-data recipes)')
    parser.add_argument('--work-dir', default=None,
                        help='default: work_dirs/compare/<set or custom>, '
                        'with _<preset> unless the preset is demo')
    parser.add_argument('--threads', type=int, default=None,
                        help='torch intra-op threads (default: torch\'s)')
    parser.add_argument('--restore', metavar='COMPARE_JSON',
                        help="a saved comparison's compare.json (e.g. "
                        'docs/accuracy/parts.json): its runs are written '
                        'into --work-dir first and not trained again')
    parser.add_argument('--report-only', action='store_true',
                        help='train and test nothing: tabulate the '
                        'finished runs in --work-dir (with --restore, the '
                        "record's) and list the ones left out")
    parser.add_argument('--jobs', type=int, metavar='N',
                        help='runs at once: N worker processes on this '
                        'machine (default: one run after another in this '
                        'process); with --executor ray, N runs in flight at '
                        'most (default: as many as the resources take)')
    parser.add_argument('--executor', choices=['local', 'ray'],
                        default='local',
                        help='local: this machine (default); ray: each run '
                        'a Ray task (Ray: requirements/serve.txt)')
    parser.add_argument('--address', metavar='RAY_ADDRESS',
                        help='the Ray cluster (ray.init address, e.g. auto '
                        'or HOST:6379; its nodes see the work dir, data and '
                        'code at the same paths); default: a local Ray on '
                        'this machine, --jobs x --run-cpus CPUs')
    parser.add_argument('--run-cpus', type=float, default=None,
                        help='CPUs of each run on Ray (default 1)')
    parser.add_argument('--run-gpus', type=float, default=None,
                        help='GPUs of each run on Ray (default 0: on the '
                        'CPU; 0.5: two runs share a GPU)')
    parser.add_argument('--no-wait', action=Removed,
                        why='runs are no longer locked; one command runs '
                        "every run of its work dir (several at once: --jobs "
                        'N, or --executor ray)')
    parser.add_argument('--cfg-options', nargs='+', action=DictAction,
                        help='overrides applied to every config; each run '
                        'records them, and a run trained with other '
                        'overrides is refused (give the same ones, e.g. '
                        'with --report-only, or another --work-dir)')
    args = parser.parse_args(argv)
    if args.set is None and not args.configs:
        parser.error('give --set or --configs')
    variants = [item.partition('=') for item in args.weights_of]
    if any(not name or not sep or not source
           for name, sep, source in variants):
        parser.error(f'--weights-of NAME=SOURCE, got {args.weights_of}')
    args.weights_of = {name: source for name, _, source in variants}
    if args.preset is None:
        args.preset = SET_PRESETS.get(args.set, 'demo')
    preset = PRESETS[args.preset]
    # data_root is filled in main(): real-data recipes take their config's
    for key in ('iters', 'batch_size', 'warmup_iters', 'img_scale',
                'transfer_root'):
        if getattr(args, key) is None:
            setattr(args, key, getattr(preset, key))
    if args.iters < 0 or args.batch_size < 1 or not args.seeds:
        parser.error('--iters >= 0, --batch-size >= 1 and one seed or more')
    if args.jobs is not None and args.jobs < 1:
        parser.error('--jobs N: N >= 1')
    ray_only = [f'--{k.replace("_", "-")}' for k in (
        'address', 'run_cpus', 'run_gpus') if getattr(args, k) is not None]
    if ray_only and args.executor != 'ray':
        parser.error(f'{" ".join(ray_only)}: for --executor ray')
    return args


def data_and_betas(args, recipes) -> tuple:
    """``--data-root`` and ``--betas``, or their defaults: recipes written
    for real data (:func:`cbnet_lab.plan.reference_condition`) test their
    config's data and no betas; the others the preset's data root and
    three betas."""
    from cbnet_lab import recipe_comparison as rc
    from cbnet_lab.config_edits import read_config
    real = rc.reference_condition(recipes) != 'clear'
    betas, data_root = args.betas, args.data_root
    if betas is None:
        betas = [] if real else [0.005, 0.01, 0.02]
    if data_root is None:
        data_root = read_config(recipes[0][1]).data_root if real \
            else rc.PRESETS[args.preset].data_root
    return data_root, betas


def executor_of(args):
    """Where the runs run (``--executor``, ``--jobs``); nothing for a
    tabulation (``--report-only``)."""
    from contextlib import nullcontext

    from cbnet_lab.executors import make_executor
    if args.report_only:
        return nullcontext()
    return make_executor(
        args.executor, args.jobs, args.address,
        1 if args.run_cpus is None else args.run_cpus,
        0 if args.run_gpus is None else args.run_gpus, args.threads)


def main(argv=None) -> dict:
    args = parse_args(argv)
    import os.path as osp

    import torch

    from cbnet_lab import recipe_comparison as rc
    from cbnet_lab.config_edits import Budget
    if args.threads:
        torch.set_num_threads(args.threads)
    recipes = rc.resolve_recipes(args.set, args.configs, args.only)
    data_root, betas = data_and_betas(args, recipes)
    name = args.set or 'custom'
    if args.preset not in ('demo', rc.SET_PRESETS.get(args.set)):
        name += f'_{args.preset}'
    work_dir = args.work_dir or osp.join('work_dirs', 'compare', name)
    budget = Budget(
        iters=args.iters, batch_size=args.batch_size, lr=args.lr,
        warmup_iters=args.warmup_iters, num_workers=args.num_workers,
        img_scale=tuple(args.img_scale) if args.img_scale else None)
    if args.restore:
        n = rc.restore_runs(args.restore, work_dir, budget)
        print(f'restored {n} finished run(s) from {args.restore}')
    with executor_of(args) as executor:
        record = rc.compare(recipes, args.seeds, budget, data_root,
                            betas, work_dir, args.cfg_options,
                            set_name=args.set, train=not args.report_only,
                            transfer_root=args.transfer_root,
                            ceiling_record=args.ceiling,
                            weights_from=args.weights_from,
                            executor=executor, weights_of=args.weights_of)
    print(f'written: {osp.join(work_dir, "compare.json")}, compare.md, '
          'compare.png')
    return record


if __name__ == '__main__':
    main(sys.argv[1:])
