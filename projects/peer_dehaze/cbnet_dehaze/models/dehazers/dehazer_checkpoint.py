"""Load a dehazer's weights on their own, saying what did not load."""
from typing import Dict, List, Optional

from mmengine.logging import MMLogger
from torch import nn

from cbnet_mmdet.utils.checkpoint.fit import compare_state_dicts, listed
from cbnet_mmdet.utils.checkpoint.files import (read_checkpoint,
                                                unwrap_state_dict)

#: Where a dehazer's weights sit inside the checkpoints this package
#: writes: the dehazer training model (``dehazer.``), a detector with a
#: ``CBNetDehazeDataPreprocessor`` (``data_preprocessor.dehazer.``), and
#: a plain ``state_dict()`` of the dehazer (no prefix).
PREFIXES = ('', 'dehazer.', 'data_preprocessor.dehazer.')


def extract_dehazer_state(state: Dict, model_keys) -> Dict:
    """Pick the prefix of ``state`` under which most dehazer keys exist.

    Args:
        state (dict[str, Tensor]): A checkpoint's state dict.
        model_keys: The dehazer's ``state_dict()`` keys.

    Returns:
        dict[str, Tensor]: The keys under the best prefix, prefix removed
        (the whole ``state`` when no prefix matches any key).
    """
    model_keys = set(model_keys)
    best, best_hits = state, 0
    for prefix in PREFIXES:
        sub = {k[len(prefix):]: v for k, v in state.items()
               if k.startswith(prefix)}
        hits = len(model_keys & set(sub))
        if hits > best_hits:
            best, best_hits = sub, hits
    return best


def load_dehazer_checkpoint(dehazer: nn.Module,
                            filename: str,
                            strict: bool = True,
                            logger: Optional[MMLogger] = None
                            ) -> Dict[str, List[str]]:
    """Load the weights of a dehazer from a checkpoint file.

    The file may be an MMEngine checkpoint of the dehazer training model
    (``projects/peer_dehaze/tools/train_dehazer.py``), of a detector with a
    dehazing data preprocessor, or a bare state dict. It is read by
    :func:`~cbnet_mmdet.utils.checkpoint.files.read_checkpoint`
    (``torch.load(weights_only=True)`` with the package's allow-list,
    errors naming the file). Tensors whose name and shape fit are copied.

    Args:
        dehazer (nn.Module): The built dehazer.
        filename (str): Checkpoint path.
        strict (bool): Raise when anything is missing, unexpected or of
            another shape (a checkpoint of another architecture or size);
            otherwise only log a warning. Defaults to True.
        logger (MMLogger, optional): Where to log; the current MMLogger
            by default.

    Returns:
        dict[str, list[str]]: ``loaded``, ``missing``, ``unexpected`` and
        ``mismatched`` names (see ``compare_state_dicts``).

    Raises:
        FileNotFoundError: ``filename`` does not exist.
        ValueError: it is empty, damaged or not a checkpoint.
        RuntimeError: ``strict`` and the checkpoint does not fit, or no
            tensor fits at all; the message lists what did not load.
    """
    logger = logger or MMLogger.get_current_instance()
    # checked, weights-only reading with the package's allow-list: a
    # missing, empty, damaged or non-checkpoint file is named in the error
    state = unwrap_state_dict(read_checkpoint(filename))
    model_state = dehazer.state_dict()
    state = extract_dehazer_state(state, model_state)
    report = compare_state_dicts(model_state, state)
    problems = [(k, report[k])
                for k in ('missing', 'unexpected', 'mismatched')
                if report[k]]
    summary = (f'{type(dehazer).__name__}: {len(report["loaded"])} of '
               f'{len(model_state)} tensors fit in {filename}')
    details = '\n'.join(f'  {k} ({len(v)}): {listed(v)}'
                        for k, v in problems)
    if problems and (strict or not report['loaded']):
        raise RuntimeError(
            f'{summary}; is it a checkpoint of this dehazer architecture '
            f'and size? Not loaded:\n{details}')
    loaded = {k: state[k] for k in report['loaded']}
    dehazer.load_state_dict(loaded, strict=False)
    logger.info(summary)
    if problems:
        logger.warning(f'not loaded from {filename}:\n{details}')
    return report
