"""Bounded load test of a running model server.

Usage::

    python projects/edge_serving/tools/load_test.py http://127.0.0.1:8000 \
        [--image IMG | --images FOLDER | --size 512 1024] \
        [--concurrency 1 2 4] \
        [--requests 8] [--timeout-s 120] [--out result.json]

For each concurrency C, C client threads send ``--requests`` requests in
all (divided among them) and stop: the run is bounded by the request
count, and every request by ``--timeout-s``. Prints one markdown row per
C: latency p50 / p90 / p99 (s), throughput (images/s), errors.

``--images FOLDER`` sends the folder's photos (searched recursively,
sorted) in turn, each as its file's bytes (a JPEG stays a JPEG), so that a
level's requests are real frames of their own sizes rather than one image
sent again.
"""
import argparse
import json
import os.path as osp
import time
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import requests


def parse_args(argv=None):
    p = argparse.ArgumentParser(description='bounded server load test')
    p.add_argument('url')
    src = p.add_mutually_exclusive_group()
    src.add_argument('--image', help='image file to send')
    src.add_argument('--images', help='folder of images to send in turn')
    p.add_argument('--size', type=int, nargs=2, default=(512, 1024),
                   metavar=('H', 'W'),
                   help='random image size when no --image')
    p.add_argument('--concurrency', type=int, nargs='+', default=[1, 2, 4])
    p.add_argument('--requests', type=int, default=8,
                   help='requests per concurrency level')
    p.add_argument('--timeout-s', type=float, default=120)
    p.add_argument('--out', help='write the results as JSON')
    return p.parse_args(argv)


def folder_bodies(folder):
    """``(body, content type, (h, w))`` of each image under ``folder``."""
    from cbnet_serving.stream import IMAGE_TYPES, list_images
    out = []
    for f in list_images(folder):
        img = cv2.imread(f)
        if img is None:
            raise ValueError(f'cannot decode {f}')
        with open(f, 'rb') as fh:
            out.append((fh.read(), IMAGE_TYPES[osp.splitext(f)[1].lower()],
                        img.shape[:2]))
    return out


def one(url, body, content_type='image/png', timeout=120):
    start = time.perf_counter()
    try:
        ok = requests.post(url + '/predict', data=body, timeout=timeout,
                           headers={'Content-Type': content_type}
                           ).status_code == 200
    except requests.RequestException:
        ok = False
    return ok, time.perf_counter() - start


def level(url, bodies, concurrency, n, timeout):
    """``n`` requests from ``concurrency`` threads; request ``i`` sends
    ``bodies[i % len(bodies)]`` (``(body, content type)`` pairs)."""
    start = time.perf_counter()
    with ThreadPoolExecutor(concurrency) as pool:
        res = list(pool.map(
            lambda i: one(url, *bodies[i % len(bodies)][:2],
                          timeout=timeout), range(n)))
    wall = time.perf_counter() - start
    lat = np.array([t for ok, t in res if ok])
    q = (np.percentile(lat, [50, 90, 99]).round(3).tolist()
         if lat.size else [None] * 3)
    return dict(concurrency=concurrency, requests=n,
                errors=sum(not ok for ok, _ in res), p50_s=q[0], p90_s=q[1],
                p99_s=q[2], throughput_img_s=round(lat.size / wall, 3),
                wall_s=round(wall, 2))


def main(argv=None):
    args = parse_args(argv)
    if args.images:
        bodies = folder_bodies(args.images)
    else:
        if args.image:
            img = cv2.imread(args.image)
            if img is None:
                raise FileNotFoundError(f'cannot read --image {args.image}')
        else:
            img = np.random.default_rng(0).integers(
                0, 256, (*args.size, 3)).astype(np.uint8)
        bodies = [(cv2.imencode('.png', img)[1].tobytes(), 'image/png',
                   img.shape[:2])]
    # warm-up, not counted
    one(args.url, *bodies[0][:2], timeout=args.timeout_s)
    rows = [level(args.url, bodies, c, args.requests, args.timeout_s)
            for c in args.concurrency]
    print('| concurrency | requests | p50 s | p90 s | p99 s | img/s | '
          'errors |')
    print('|---|---|---|---|---|---|---|')
    for r in rows:
        print(f"| {r['concurrency']} | {r['requests']} | {r['p50_s']} | "
              f"{r['p90_s']} | {r['p99_s']} | {r['throughput_img_s']} | "
              f"{r['errors']} |")
    if args.out:
        with open(args.out, 'w') as f:
            shapes = sorted({tuple(b[2]) for b in bodies})
            json.dump(dict(images=len(bodies),
                           image_shapes=[list(x) for x in shapes],
                           source=args.images or args.image or 'random',
                           levels=rows), f, indent=1)


if __name__ == '__main__':
    main()
