"""Map SegFormer MiT checkpoints to :class:`CBNetMiT`'s parameter layout.

:class:`CBNetMiT` uses mmsegmentation's ``MixVisionTransformer`` layout
(identical to MMDetection's PVTv2): ``layers.{i}.0.projection``,
``layers.{i}.1.{j}.attn.attn.in_proj_weight``, ``...ffn.layers.{0,1,4}``,
``layers.{i}.2``. Two source layouts are recognised:

* ``'mmseg'``: mmsegmentation's converted checkpoints (also MMDetection's
  PVTv2) - loaded as they are;
* ``'official'``: the SegFormer ImageNet checkpoints ``mit_b*.pth``
  (``patch_embed1.proj``, ``block1.0.attn.q`` / ``attn.kv``,
  ``mlp.fc1``, ``norm1``, ``head``) - converted with MMDetection's
  ``pvt_convert`` (PVTv2 and MiT share the official key names): ``q`` and
  ``kv`` are concatenated into ``in_proj_*``, linear FFN weights become
  1x1 convolutions.

Keys that belong to no backbone parameter (the ImageNet classifier
``head.*``, a segmentor's ``decode_head.*``) are returned as *ignored* so
the caller can log them; everything else is passed on and left to
``load_state_dict`` to report as missing or unexpected.
"""
from collections import OrderedDict
from typing import Dict, List, Tuple

from mmdet.models.backbones.pvt import pvt_convert
from torch import Tensor

from ...utils.checkpoint.files import unwrap_state_dict

#: Prefixes of official-layout keys that have no counterpart in a backbone.
OFFICIAL_NON_BACKBONE = ('head.', 'norm.', 'cls_token')


def detect_mit_layout(state_dict: Dict[str, Tensor]) -> str:
    """``'mmseg'`` or ``'official'``; ``ValueError`` if neither."""
    keys = list(state_dict)
    if any(k.startswith('layers.') for k in keys):
        return 'mmseg'
    if any(k.startswith(('patch_embed1.', 'block1.')) for k in keys):
        return 'official'
    raise ValueError('not a MiT checkpoint: expected keys starting with '
                     "'layers.' (mmseg) or 'patch_embed1.'/'block1.' "
                     f'(official SegFormer), got e.g. {keys[:5]}')


def convert_mit_checkpoint(
        checkpoint: Dict) -> Tuple['OrderedDict[str, Tensor]', List[str], str]:
    """Bring a MiT checkpoint into :class:`CBNetMiT`'s layout.

    Args:
        checkpoint (dict): A loaded checkpoint: plain state dict, or a dict
            with ``state_dict``/``model``. Prefixes ``module.`` (DDP) and
            ``backbone.`` (a whole segmentor/detector) are stripped; with
            ``backbone.`` present, the other keys are ignored.

    Returns:
        tuple: ``(state_dict, ignored_keys, layout)``; ``ignored_keys``
        are source keys deliberately not loaded (to be logged).
    """
    state_dict = unwrap_state_dict(checkpoint)
    state_dict = OrderedDict(
        (k[len('module.'):] if k.startswith('module.') else k, v)
        for k, v in state_dict.items())
    ignored = []
    if any(k.startswith('backbone.') for k in state_dict):
        ignored = [k for k in state_dict if not k.startswith('backbone.')]
        state_dict = OrderedDict((k[len('backbone.'):], v)
                                 for k, v in state_dict.items()
                                 if k.startswith('backbone.'))
    layout = detect_mit_layout(state_dict)
    if layout == 'official':
        ignored += [
            k for k in state_dict if k.startswith(OFFICIAL_NON_BACKBONE)
        ]
        state_dict = pvt_convert(state_dict)
    return state_dict, ignored, layout
