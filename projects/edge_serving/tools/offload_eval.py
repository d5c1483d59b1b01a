"""Offload rate vs AP of the edge router (projects/edge_serving/README.md).

Usage::

    # the same frames through route.py twice (and, optionally, live)
    python projects/edge_serving/tools/route.py LOCAL_CFG LOCAL_CKPT \
        --input FRAMES --out-dir OUT/local --mode local
    python projects/edge_serving/tools/route.py LOCAL_CFG LOCAL_CKPT \
        --input FRAMES --out-dir OUT/server --mode server
    python projects/edge_serving/tools/offload_eval.py OUT/local OUT/server \
        --ann ANN_JSON [--auto OUT/auto] [--thresholds 0.5 0.6 0.7] \
        [--confidences 0.3 0.5] \
        [--router-cfg projects/edge_serving/tools/edge_router.py] \
        [--calibrate] [--out-dir OUT]

``ANN_JSON`` is the COCO instances file of the clear images; foggy frames
(``*_leftImg8bit_foggy_beta_{b}.png``) take their clear twin's annotations.
Writes ``OUT/offload.json`` and ``OUT/offload.md`` and prints the table.
"""
import argparse
import os.path as osp


def parse_args(argv=None):
    here = osp.dirname(osp.abspath(__file__))
    p = argparse.ArgumentParser(
        description='offload rate vs AP of the edge router')
    p.add_argument('local', help='route.py --mode local output folder')
    p.add_argument('server', help='route.py --mode server output folder')
    p.add_argument('--ann', required=True,
                   help='COCO instances JSON of the clear images')
    p.add_argument('--auto', help='route.py --mode auto output folder, '
                   'scored as routed')
    p.add_argument('--thresholds', type=float, nargs='+',
                   help='transmission thresholds of the haze rule '
                   '(default: deciles of the frames\' transmission)')
    p.add_argument('--confidences', type=float, nargs='+',
                   help='local top-score thresholds of the confidence rule '
                   '(default: deciles of the local top scores)')
    p.add_argument('--router-cfg', default=osp.join(here, 'edge_router.py'),
                   help='its transmission_thr / min_confidence are the '
                   '"shipped" row')
    p.add_argument('--boxes-only', action='store_true',
                   help='score boxes only (models or data without masks)')
    p.add_argument('--calibrate', action='store_true',
                   help="map each model's scores onto the precision they "
                   'stand for (isotonic, per class, cross-fitted on two '
                   'halves of the frames) before the two are ranked '
                   'together; not with --auto')
    p.add_argument('--conditions', choices=('beta', 'folder'),
                   default='beta',
                   help="a frame's condition: 'beta' from Foggy Cityscapes "
                   "names (*_foggy_beta_B; annotations of the clear twin), "
                   "'folder' from its first folder (make_stream.py's "
                   'layout; annotations by the frame path)')
    p.add_argument('--out-dir', help='default: the local folder')
    return p.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    from mmengine.config import Config

    from cbnet_serving.offload import offload_curve, to_markdown, write
    from cbnet_serving.router import RouterConfig
    router = RouterConfig(
        **dict(Config.fromfile(args.router_cfg).get('router', {})))
    result = offload_curve(
        args.local, args.server, args.ann, thresholds=args.thresholds,
        confidences=args.confidences,
        policy=dict(transmission_thr=router.transmission_thr,
                    min_confidence=router.min_confidence),
        auto_dir=args.auto,
        metrics=('bbox', ) if args.boxes_only else ('bbox', 'segm'),
        calibrate=args.calibrate, conditions=args.conditions)
    paths = write(result, args.out_dir or args.local)
    print(to_markdown(result))
    print(f"written: {paths['json']}, {paths['markdown']}")
    return result


if __name__ == '__main__':
    main()
