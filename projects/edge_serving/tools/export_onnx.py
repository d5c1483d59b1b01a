"""Export an MMDet YOLOX (config + checkpoint) to one ONNX file for the
edge router: the network, the box decoding and the NMS in the graph, the
preprocessing in its metadata (projects/edge_serving/README.md, "The edge
model").

Usage::

    python projects/edge_serving/tools/export_onnx.py CONFIG CHECKPOINT \
        --out EDGE.onnx [--shape H W] [--check IMAGE [IMAGE ...]]

By default the graph takes any input size and every image gets the input
the PyTorch model gets (resized as the test pipeline resizes, padded to the
preprocessor's divisor); ``--shape H W`` fixes the input instead (384 640
is a 640x360 camera frame exactly as the PyTorch model pads it). ``--check`` runs the file on
ONNX Runtime and the PyTorch model (``DetInferencer``) on the images and
prints, per image, both detection counts and the largest box and score
gaps; it exits 1 when the two disagree in count or labels.
"""
import argparse
import json
import os.path as osp
import sys


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('config')
    p.add_argument('checkpoint', nargs='?',
                   help='trained weights (strict load); without it the '
                   "config's own initialisation is exported")
    p.add_argument('--out', required=True, help='the .onnx file to write')
    p.add_argument('--shape', type=int, nargs=2, metavar=('H', 'W'))
    p.add_argument('--opset', type=int, default=11)
    p.add_argument('--check', nargs='+', metavar='IMAGE',
                   help='images to compare ONNX Runtime with PyTorch on')
    args = p.parse_args(argv)
    if args.shape and min(args.shape) < 1:
        p.error(f'--shape must be two positive integers, got {args.shape}')
    if not args.out.endswith('.onnx'):
        p.error(f'--out {args.out}: give a file name ending in .onnx')
    args.error = p.error
    return args


def check_files(args) -> None:
    """Every --check image exists (a usage error naming the first that
    does not, before anything is loaded or written)."""
    for path in args.check or ():
        if not osp.isfile(path):
            args.error(f'--check {path}: no such file')


def main(argv=None):
    args = parse_args(argv)
    check_files(args)
    import mmcv

    from cbnet_serving.export import detections_gap, export_yolox
    meta = export_yolox(args.config, args.checkpoint, args.out,
                        shape=args.shape, opset=args.opset)
    shape = meta['input_shape'] or 'any size (H, W), padded to ' \
        f"{meta['pad_size_divisor']}"
    print(f"written {args.out}: input {shape}, "
          f"{len(meta['classes'])} classes, resize {meta['resize']}")
    if not args.check:
        return meta
    images = []
    for path in args.check:
        img = mmcv.imread(path)
        if img is None:
            raise SystemExit(f'--check {path}: not a readable image')
        images.append(img)
    gap = detections_gap(args.out, args.config, args.checkpoint, images)
    for path, row in zip(args.check, gap['images']):
        print(f'{path}: {json.dumps(row)}')
    print('ONNX Runtime and PyTorch agree' if gap['equal'] else
          'ONNX Runtime and PyTorch DISAGREE (counts or labels)')
    if not gap['equal']:
        sys.exit(1)
    return meta


if __name__ == '__main__':
    main()
