"""Serve a detector over HTTP on this machine (Ray Serve).

Usage::

    python projects/edge_serving/tools/serve.py CONFIG [CHECKPOINT] \
        [--port 8000] \
        [--host 127.0.0.1] [--replicas 1] [--max-batch-size 4] \
        [--batch-wait-ms 10] [--device cpu]

Without CHECKPOINT the model runs with its own random initialisation
(``/info`` says so). Stop with Ctrl-C or SIGTERM.
projects/edge_serving/README.md has the API and how to run it on a Ray
cluster.
"""
import argparse
import os


def parse_args(argv=None):
    p = argparse.ArgumentParser(description='Serve a cbnet_mmdet detector')
    p.add_argument('config', help='detector config file')
    p.add_argument('checkpoint', nargs='?', help='checkpoint file')
    p.add_argument('--host', default='127.0.0.1')
    p.add_argument('--port', type=int, default=8000)
    p.add_argument('--device', default='cpu')
    p.add_argument('--replicas', type=int, default=1)
    p.add_argument('--max-batch-size', type=int, default=4)
    p.add_argument('--batch-wait-ms', type=float, default=10.0)
    p.add_argument('--max-pixels', type=int, default=4096 * 4096)
    p.add_argument('--num-cpus', type=int,
                   help='CPUs Ray may use (default: all)')
    return p.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    os.environ.setdefault('OMP_NUM_THREADS', '1')
    from cbnet_serving.server import run_local
    run_local(args.config, args.checkpoint, host=args.host, port=args.port,
              num_cpus=args.num_cpus, device=args.device,
              num_replicas=args.replicas,
              max_batch_size=args.max_batch_size,
              batch_wait_timeout_s=args.batch_wait_ms / 1000,
              max_pixels=args.max_pixels)


if __name__ == '__main__':
    main()
