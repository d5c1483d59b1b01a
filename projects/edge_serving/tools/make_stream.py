"""Lay out real frames of several labelled sets as one stream, by condition.

Usage::

    python projects/edge_serving/tools/make_stream.py OUT \
        --voc fog=data/dawn_fog \
        --coco clear=data/coco_street/annotations/instances_val.json:\
data/coco_street/images

Writes ``OUT/frames/{condition}/{name}`` (links to the photos) and
``OUT/annotations.json`` (COCO instances, the project's classes, one image
per frame with its path as ``file_name``). A VOC folder gives its seeded
val split (the real-fog configs' 30 %, seed 0); a COCO file every image it
lists. Then route.py over ``OUT/frames`` and
``offload_eval.py ... --ann OUT/annotations.json --conditions folder
--boxes-only`` (projects/edge_serving/README.md).
"""
import argparse


def pair(text, parts):
    cond, sep, rest = text.partition('=')
    values = rest.split(':') if sep else []
    if not cond or len(values) != parts or not all(values):
        form = 'COND=VOC_DIR' if parts == 1 else 'COND=ANN_JSON:IMG_DIR'
        raise argparse.ArgumentTypeError(f'{text!r}: expected {form}')
    return (cond, *values)


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('out_dir')
    p.add_argument('--voc', nargs='+', default=[],
                   type=lambda t: pair(t, 1), metavar='COND=VOC_DIR')
    p.add_argument('--coco', nargs='+', default=[],
                   type=lambda t: pair(t, 2),
                   metavar='COND=ANN_JSON:IMG_DIR')
    args = p.parse_args(argv)
    if not args.voc and not args.coco:
        p.error('give at least one --voc or --coco source')
    return args


def main(argv=None):
    args = parse_args(argv)
    from cbnet_serving.stream import build_stream
    out = build_stream(args.out_dir, voc=args.voc, coco=args.coco)
    counts = ', '.join(f'{c}: {n}' for c, n in out['counts'].items())
    print(f"frames: {out['frames']} ({counts}); annotations: "
          f"{out['ann_file']}; {out['dropped']} annotations of other "
          'classes dropped')
    return out


if __name__ == '__main__':
    main()
