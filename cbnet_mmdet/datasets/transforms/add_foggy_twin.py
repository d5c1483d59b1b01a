"""The foggy twin of a clear photograph, stacked as CBNet-DD's pair."""
import numpy as np
from mmdet.registry import TRANSFORMS

from .add_fog import CBNetAddFog


@TRANSFORMS.register_module()
class CBNetAddFoggyTwin(CBNetAddFog):
    """Stack a clear image with its synthetic foggy twin, on the fly.

    Turns the clear ``uint8[H, W, 3]`` image of any detection dataset into
    the 6-channel pair that ``CBNetLoadPairedImageFromFile`` reads from
    Foggy Cityscapes files: the foggy image (:class:`CBNetAddFog`'s fog,
    same knobs) in channels 0-2, the clear image in channels 3-5. Place it
    right after ``LoadImageFromFile`` (and ``LoadAnnotations``): the row
    prior then sees the whole photograph, and every later geometric
    transform (``RandomResize``, ``RandomCrop``, ``RandomFlip``) crops,
    flips and resizes both halves identically, so the student and the
    teacher of ``CBNetDistiller`` see the same crop. As with the file
    pairs, no photometric transform or ``Pad`` may follow (see
    ``CBNetPairedFoggyDataset.UNSUPPORTED_TRANSFORMS``), and the model
    needs ``CBNetPairedDataPreprocessor``.

    When ``prob`` skips an image its twin is a copy of the clear image
    (``fog_beta`` 0.0). Input checks and errors are those of
    :class:`CBNetAddFog` (a 6-channel image is refused: it is paired
    already).

    Required keys: ``img``. Modified keys: ``img`` (``H x W x 6``, the
    input's dtype). Added keys: ``fog_beta``, ``fog_light``.

    Args:
        **kwargs: :class:`CBNetAddFog`'s (``beta``, ``prob``,
            ``atmospheric_light``, the row prior's camera).
    """

    def transform(self, results: dict) -> dict:
        """Replace ``results['img']`` by ``[foggy, clear]`` channels.

        Args:
            results (dict): With the clear ``img`` (``H x W x 3``).

        Returns:
            dict: ``results`` with ``img`` ``H x W x 6``, ``fog_beta``,
            ``fog_light``.
        """
        clear = self._check_image(results)
        results = super().transform(results)
        results['img'] = np.concatenate([results['img'], clear], axis=2)
        return results
