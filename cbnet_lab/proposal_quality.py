"""What the RPN of a trained model hands its RoI heads: recall of the
ground truth and the share of positives among the test-time proposals;
the engine of ``tools/analysis_tools/proposal_quality.py`` (which
documents the statistics).

:func:`proposal_quality` measures a built model over a dataset,
:func:`evaluate` one config and checkpoint on its test split,
:func:`to_markdown` tabulates.
"""
from typing import Optional

import torch
from mmengine.dataset import pseudo_collate

from cbnet_tools.markdown import markdown_table

RECALL_IOUS = (0.5, 0.7, 0.9)
POSITIVE_IOUS = (0.5, 0.6, 0.7)


def proposal_quality(model, dataset, max_images=None) -> dict:
    """Proposal statistics of ``model`` (eval mode) over ``dataset``."""
    from mmdet.structures.bbox import bbox_overlaps
    best_per_gt, best_per_proposal, counts = [], [], []
    num = len(dataset) if max_images is None else min(max_images,
                                                      len(dataset))
    with torch.no_grad():
        for i in range(num):
            data = model.data_preprocessor(pseudo_collate([dataset[i]]),
                                           False)
            sample = data['data_samples'][0]
            feats = model.extract_feat(data['inputs'])
            props = model.rpn_head.predict(
                feats, data['data_samples'], rescale=False)[0].bboxes
            gt = sample.gt_instances.bboxes
            gt = getattr(gt, 'tensor', gt).to(props)
            # GT boxes are in the original image; proposals in the resized
            sx, sy = sample.metainfo['scale_factor']
            gt = gt * gt.new_tensor([sx, sy, sx, sy])
            counts.append(len(props))
            ious = bbox_overlaps(gt, props)
            if len(gt) and len(props):
                best_per_gt.append(ious.max(1).values)
                best_per_proposal.append(ious.max(0).values)
            else:
                best_per_gt.append(props.new_zeros(len(gt)))
                best_per_proposal.append(props.new_zeros(len(props)))
    per_gt = torch.cat(best_per_gt) if best_per_gt else torch.zeros(0)
    per_prop = (torch.cat(best_per_proposal) if best_per_proposal else
                torch.zeros(0))

    def share(values, t):
        return float((values >= t).float().mean()) if len(values) else 0.

    return dict(
        images=num,
        gt_boxes=len(per_gt),
        proposals_per_image=sum(counts) / max(num, 1),
        recall={str(t): share(per_gt, t) for t in RECALL_IOUS},
        mean_best_iou=float(per_gt.mean()) if len(per_gt) else 0.,
        positive_share={str(t): share(per_prop, t) for t in POSITIVE_IOUS})


def evaluate(config: str, checkpoint: str, data_root: Optional[str] = None,
             max_images: Optional[int] = None, device: str = 'cpu') -> dict:
    """:func:`proposal_quality` of a trained model on its config's test
    dataset (``data_root`` replaces the dataset's)."""
    from mmdet.registry import DATASETS
    from mmengine.config import Config
    from mmengine.registry import init_default_scope

    import cbnet_mmdet  # noqa: F401  (registers the components)
    from cbnet_mmdet.utils.checkpoint.fit import init_checked_detector
    init_default_scope('mmdet')
    cfg = Config.fromfile(config)
    dataset_cfg = cfg.test_dataloader.dataset
    if data_root:
        dataset_cfg.data_root = data_root
    model = init_checked_detector(cfg, checkpoint, device=device)
    return proposal_quality(model, DATASETS.build(dataset_cfg), max_images)


def to_markdown(results: dict) -> str:
    head = (['model', 'proposals / image'] +
            [f'recall@{t}' for t in RECALL_IOUS] + ['mean best IoU'] +
            [f'proposals IoU>={t}' for t in POSITIVE_IOUS])
    return '\n'.join(markdown_table(head, [
        [name, f"{r['proposals_per_image']:.0f}"] +
        [f"{r['recall'][str(t)]:.3f}" for t in RECALL_IOUS] +
        [f"{r['mean_best_iou']:.3f}"] +
        [f"{r['positive_share'][str(t)]:.3f}" for t in POSITIVE_IOUS]
        for name, r in results.items()
    ]))
