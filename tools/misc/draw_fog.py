"""Draw a generated scene's depth-rendered fog beside CBNetAddFog's fog.

Usage::

    python tools/misc/generate_cityscapes_like.py /tmp/fogpic_data \
        --num-train 1 --num-val 1 --seed 0
    python tools/misc/draw_fog.py /tmp/fogpic_data \
        --out docs/robustness/fog_row_prior.png

One row per ``--betas`` value; the columns: the fog the generator renders
from the scene's own depth (its ``leftImg8bit_foggy`` twin), then
``CBNetAddFog`` on the clear image with its defaults (the distance of each
row from a flat road and a 2 m ceiling: what it does to a photograph
without depth) and without a ceiling. Each panel is titled in words and
gives its mean absolute difference to the depth-rendered fog; the caption
says what the band along the horizon row is.
"""
import argparse
import glob
import os
import os.path as osp

import numpy as np

#: What each column is, in words.
COLUMNS = ("fog rendered from the scene's depth",
           'CBNetAddFog (rows as a flat road, 2 m ceiling)',
           'CBNetAddFog without a ceiling')
CAPTION = ("The bright band in CBNetAddFog's panels is its horizon row: "
           'the row prior puts it at max_distance (600 m, transmission '
           'about 0) whatever stands there; without a ceiling every row '
           'above it is that far.')


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('root', help='a generated Cityscapes-like tree '
                   '(tools/misc/generate_cityscapes_like.py)')
    p.add_argument('--betas', type=float, nargs='+',
                   default=[0.005, 0.01, 0.02])
    p.add_argument('--split', default='val')
    p.add_argument('--out', required=True, help='the PNG to write')
    args = p.parse_args(argv)
    if any(b <= 0 for b in args.betas):
        p.error(f'--betas must be > 0, got {args.betas}')
    return args


def scene(root: str, split: str, betas) -> tuple:
    """The first clear image of the split and its foggy twins.

    Raises:
        FileNotFoundError: no clear image, or a twin missing (named, with
            the command that renders it).
    """
    clear = sorted(glob.glob(osp.join(root, 'leftImg8bit', split, '*',
                                      '*_leftImg8bit.png')))
    if not clear:
        raise FileNotFoundError(
            f'no {split} image under {root}/leftImg8bit/{split}: generate '
            f'one with python tools/misc/generate_cityscapes_like.py {root} '
            '--num-train 1 --num-val 1')
    image = clear[0]
    twins = []
    for beta in betas:
        twin = image.replace(osp.join('leftImg8bit', split),
                             osp.join('leftImg8bit_foggy', split)).replace(
                                 '_leftImg8bit.png',
                                 f'_leftImg8bit_foggy_beta_{beta:g}.png')
        if not osp.isfile(twin):
            raise FileNotFoundError(
                f'{twin}: no depth-rendered fog at beta {beta:g}; render it '
                f'with python tools/misc/generate_cityscapes_like.py {root} '
                f'--betas {" ".join(f"{b:g}" for b in betas)}')
        twins.append(twin)
    return image, twins


def main(argv=None):
    args = parse_args(argv)
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import mmcv

    from cbnet_mmdet.datasets.transforms import CBNetAddFog
    image, twins = scene(args.root, args.split, args.betas)
    clear = mmcv.imread(image)  # BGR, as the pipelines load it
    rows = len(args.betas)
    fig, axes = plt.subplots(rows, 3, figsize=(12, 2.6 * rows + 0.6),
                             squeeze=False)
    for r, (beta, twin) in enumerate(zip(args.betas, twins)):
        rendered = mmcv.imread(twin)
        panels = [rendered]
        for ceiling in (2.0, None):
            fogged, _ = CBNetAddFog(beta=beta,
                                    ceiling_height=ceiling).fog(clear, beta)
            panels.append(fogged)
        for c, panel in enumerate(panels):
            ax = axes[r][c]
            ax.imshow(panel[..., ::-1])
            ax.set_axis_off()
            title = f'{COLUMNS[c]}, beta {beta:g}'
            if c:
                diff = np.abs(panel.astype(float) - rendered).mean()
                title += f'\n{diff:.1f} grey levels from the depth fog'
            ax.set_title(title, fontsize=8)
    fig.text(0.5, 0.01, CAPTION, ha='center', va='bottom', fontsize=8,
             wrap=True)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    fig.savefig(args.out, dpi=100)
    plt.close(fig)
    print(f'drawn: {args.out} ({osp.basename(image)}, betas '
          f'{" ".join(f"{b:g}" for b in args.betas)})')


if __name__ == '__main__':
    main()
