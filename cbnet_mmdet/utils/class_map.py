"""Which class of a model trained on one label set stands for which class
of a dataset with another: COCO detectors on the project's 8 Cityscapes
classes or on VOC's 20.

A dataset class takes the source class of the same name, else the one
:data:`CLASS_ALIASES` names for it (VOC's ``motorbike`` is COCO's
``motorcycle``; Cityscapes' ``rider`` has no COCO class of its own: COCO
labels a rider ``person``). Used twice, with the same map:

* zero-shot evaluation (``CBNetClassMapMetric``): a COCO model's
  predictions of a source class are scored as every dataset class it
  stands for (a ``person`` box counts as ``person`` and as ``rider``),
  predictions of source classes that stand for nothing are dropped;
* fine-tuning (``cbnet_tools.yolox_weights``): a dataset class's
  classifier row starts as its source class's row (``rider`` from
  ``person``), not from nothing.
"""
from typing import Dict, List, Optional, Sequence, Tuple, Union

#: Dataset class name -> the source (COCO) class name it is scored as,
#: where the two names differ: VOC's spellings, and Cityscapes' ``rider``
#: (COCO annotates riders as ``person``).
CLASS_ALIASES = {
    'rider': 'person',
    'aeroplane': 'airplane',
    'motorbike': 'motorcycle',
    'diningtable': 'dining table',
    'pottedplant': 'potted plant',
    'sofa': 'couch',
    'tvmonitor': 'tv',
}


def coco_classes() -> Tuple[str, ...]:
    """COCO's 80 class names in MMDet's label order
    (``CocoDataset.METAINFO``)."""
    from mmdet.datasets import CocoDataset
    return tuple(CocoDataset.METAINFO['classes'])


def resolve_classes(classes: Union[str, Sequence[str]]) -> Tuple[str, ...]:
    """``classes`` as a tuple of names; ``'coco'`` is COCO's 80.

    Raises:
        ValueError: An unknown name for a class list, an empty list, or a
            name given twice.
    """
    if isinstance(classes, str):
        if classes != 'coco':
            raise ValueError(f"classes must be a sequence of names or "
                             f"'coco', got {classes!r}")
        return coco_classes()
    names = tuple(classes)
    if not names:
        raise ValueError('classes must not be empty')
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f'class names given twice: {twice}')
    return names


def class_sources(target: Sequence[str],
                  source: Union[str, Sequence[str]] = 'coco',
                  aliases: Optional[Dict[str, str]] = None
                  ) -> List[Optional[int]]:
    """The source label each target class is scored as (None: none).

    Args:
        target (Sequence[str]): The dataset's class names, in label order.
        source (str | Sequence[str]): The model's class names, or
            ``'coco'``.
        aliases (dict, optional): Target name -> source name, for targets
            whose source has another name; default :data:`CLASS_ALIASES`.
            A target's own name wins over its alias.

    Returns:
        list[int | None]: Per target label, its source label.

    Raises:
        ValueError: An alias names a class the source does not have.
    """
    source = resolve_classes(source)
    target = resolve_classes(target)
    aliases = CLASS_ALIASES if aliases is None else aliases
    index = {name: i for i, name in enumerate(source)}
    found = []
    for name in target:
        if name in index:
            found.append(index[name])
        elif name in aliases:
            if aliases[name] not in index:
                raise ValueError(
                    f'class map: {name!r} is to be scored as '
                    f'{aliases[name]!r}, which the source classes do not '
                    f'have ({len(source)} classes: {", ".join(source[:8])}'
                    '...)')
            found.append(index[aliases[name]])
        else:
            found.append(None)
    return found


def label_targets(target: Sequence[str],
                  source: Union[str, Sequence[str]] = 'coco',
                  aliases: Optional[Dict[str, str]] = None
                  ) -> List[List[int]]:
    """The inverse of :func:`class_sources`: per source label, the target
    labels its predictions are scored as (empty: dropped)."""
    num_source = len(resolve_classes(source))
    out: List[List[int]] = [[] for _ in range(num_source)]
    for t, s in enumerate(class_sources(target, source, aliases)):
        if s is not None:
            out[s].append(t)
    return out


def describe_map(target: Sequence[str],
                 source: Union[str, Sequence[str]] = 'coco',
                 aliases: Optional[Dict[str, str]] = None) -> str:
    """One line per target class: ``rider <- person``, or ``train <-
    (none: never predicted)``."""
    names = resolve_classes(source)
    lines = []
    for name, s in zip(resolve_classes(target),
                       class_sources(target, source, aliases)):
        lines.append(f'{name} <- ' + (names[s] if s is not None else
                                      '(none: never predicted)'))
    return '; '.join(lines)
