"""Malformed-input sweep: mutated annotations and images through the
dataset, the training pipeline and one training step of the demo CBNet.

Each variant is the training split of a Cityscapes-like COCO dataset
(first ``--images`` images) with ONE random mutation: of the annotation
JSON (keys removed, wrong types, degenerate or out-of-image boxes, broken
polygons/RLE, unknown, missing, renamed or reordered categories, duplicate
or mistyped ids, string ``iscrowd``, boxes disagreeing with masks, huge or
NaN coordinates, invalid JSON ...) or of one image (truncated, random
bytes, empty, grey/16-bit/RGBA, 1x1 ...) or of one image's foggy twin
(empty, truncated). The variant is then read with
``CBNetCityscapesDataset`` and the demo config's training pipeline (at
``--scale``), collated, and put through one training step (forward,
backward; no optimiser step, so every variant sees the same weights) - a
foggy-twin variant with ``CBNetPairedFoggyDataset`` and the paired loader
(CBNet-DD's input), without the step -, in a
forked child process (a segfault or a memory blow-up, capped at
``--memory-gb`` more than the parent, is a crash, not the end of the
sweep). What the dataset loaded is compared with the mutated file before
the step (:func:`audit`): every loaded instance must be an annotation of
the file with the same image, class NAME, crowd flag, box and mask, and
every annotation and image not loaded must be counted in the dataset's
``load_report`` (the drops it logs per reason, and what ``filter_cfg``
left out). Outcomes:

* ``ok``: trained, all losses and gradients finite, everything accounted
  for, nothing dropped;
* ``logged drop``: the same, with annotations dropped and logged per
  reason;
* ``clear error``: ``FileNotFoundError`` / ``ValueError`` / ``KeyError`` /
  ``TypeError`` raised by the package's own code (a check of
  ``cbnet_mmdet``, not a library error that happens to print a path) AND
  naming the mutated file (the image, or the annotation file);
* ``silent``: trained, but an annotation or image vanished without being
  counted, or an instance changed (label, crowd flag, box, mask) - a
  FAILURE, listed with the mutation;
* ``crash``: anything else (other exceptions, library errors, errors that
  name no file, non-finite losses or gradients, a killed or hung child) -
  listed with the mutation to reproduce.

Usage::

    python tools/analysis_tools/fuzz_inputs.py [--data-root DIR]
        [--variants 300] [--seed 0] [--out work_dirs/fuzz_inputs.json]

Without ``--data-root`` a tiny set (4 + 1 images at 128x256) is generated
in a temporary folder. Prints a markdown table per mutation and writes the
counts, every silent outcome and every crash as JSON.
"""
import argparse
import json
import os
import os.path as osp
import tempfile
import time

from cbnet_lab.fuzz_inputs import MUTATIONS, OUTCOMES, markdown, sweep


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--data-root', help='Cityscapes-like COCO dataset '
                        '(default: a tiny generated one)')
    parser.add_argument('--variants', type=int, default=300)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--images', type=int, default=2,
                        help='training images per variant')
    parser.add_argument('--scale', type=int, nargs=2, default=(128, 64),
                        help='Resize scale (w h) of the pipeline')
    parser.add_argument('--memory-gb', type=float, default=4,
                        help='address space a variant may use beyond the '
                        "sweep's own (its child process)")
    parser.add_argument('--mutations', nargs='+', choices=MUTATIONS,
                        help='only these (default: all, cycled)')
    parser.add_argument('--out', default='work_dirs/fuzz_inputs.json')
    return parser.parse_args()


def main():
    args = parse_args()
    with tempfile.TemporaryDirectory(prefix='cbnet_fuzz_') as tmp:
        root = args.data_root
        if root is None:
            from cbnet_tools.cityscapes_to_coco import convert
            from cbnet_tools.synthetic import \
                generate_cityscapes_like
            root = osp.join(tmp, 'data')
            generate_cityscapes_like(root, num_train=4, num_val=1,
                                     img_size=(128, 256), seed=args.seed,
                                     empty_every=3, crowd_every=2)
            convert(root)
        start = time.time()
        result = sweep(root, args.variants, args.seed, args.images,
                       tuple(args.scale), osp.join(tmp, 'variants'),
                       mutations=args.mutations, memory_gb=args.memory_gb)
        result['seconds'] = round(time.time() - start, 1)
    print(markdown(result))
    o = result['outcomes']
    print(f'\n{result["tried"]} inputs tried: ' + ', '.join(
        f'{o[k]} {k}' for k in OUTCOMES) + f'; {result["seconds"]} s')
    for item in result['silent']:
        print(f'- silent, {item["mutation"]}: {"; ".join(item["problems"])}')
    for crash in result['crashes']:
        print(f'- crash, {crash["mutation"]}: {crash["error"]}')
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(result, f, indent=1)


if __name__ == '__main__':
    main()
