"""A config's model as flat dotted keys, the keys two models differ in,
and the part of the demo recipes (trunk, neck, RPN...) each key belongs
to: what the parts configs' tests (configs/demo/parts/,
configs/pretrained/parts/ and neck/) compare."""
from cbnet_lab import config_edits as ce

#: The model keys (flattened, dotted) each part owns.
PART_KEYS = {
    'trunk': ('backbone.act_cfg', 'backbone.pos_encoding'),
    'neck': ('neck', 'data_preprocessor.pad_size_divisor'),
    'rpn': ('rpn_head', 'train_cfg.rpn', 'train_cfg.rpn_proposal.nms',
            'test_cfg.rpn.nms'),
    'iou': ('train_cfg.rcnn.0.assigner', 'train_cfg.rcnn.1.assigner',
            'train_cfg.rcnn.2.assigner'),
    'mask stage': ('roi_head.type', ),
    'mask loss': ('roi_head.mask_head', ),
    'cls': ('roi_head.bbox_head.0.loss_cls', 'roi_head.bbox_head.1.loss_cls',
            'roi_head.bbox_head.2.loss_cls'),
}


def flat(node, prefix=''):
    """``{'a.b.0.c': leaf}`` of nested dicts and lists."""
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, (list, tuple)) and any(
            isinstance(v, (dict, list, tuple)) for v in node):
        items = ((str(i), v) for i, v in enumerate(node))
    else:
        return {prefix[:-1]: list(node) if isinstance(node, tuple)
                else node}
    out = {}
    for key, value in items:
        out.update(flat(value, f'{prefix}{key}.'))
    if not out:
        out[prefix[:-1]] = type(node)()
    return out


def model_of(path):
    model = ce.read_config(path).model.to_dict()
    # the registry scope that an mmdet:: base adds, not a part of the model
    model.pop('_scope_', None)
    return flat(model)


def owner(key):
    return [p for p, keys in PART_KEYS.items()
            if any(key == k or key.startswith(k + '.') for k in keys)]


def diff(a, b):
    return {k for k in set(a) | set(b) if a.get(k, '<absent>') !=
            b.get(k, '<absent>')}


def assert_takes_part(base, row, part, source=None, label=''):
    """``row`` (flat model) is ``base`` with ``part`` changed and nothing
    else; with ``source``, what changed is ``source``'s part, whole."""
    changed = diff(base, row)
    assert changed, f'{label} changes nothing'
    assert {p for k in changed for p in owner(k)} == {part}, sorted(changed)
    if source is None:
        return
    for key in {k for k in set(base) | set(source) if part in owner(k)}:
        assert row.get(key, '<absent>') == source.get(key, '<absent>'), key
