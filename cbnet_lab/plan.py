"""What a comparison runs, checked before its first run: which recipe's
weights each recipe tests (:func:`weights_sources`), which rows train as
another set's (:func:`trained_as`), the condition every recipe is tested
on first (:func:`reference_condition`), and the data, second test sets
and pretrained files the runs need (the ``check_*`` functions), so that a
missing file stops a comparison before it trains anything.
"""
import os.path as osp
from typing import Dict, Optional, Sequence, Tuple

from cbnet_tools.pretrained import require_pretrained

from .config_edits import read_config, test_condition, transfer_test
from .sets import SET_TRAINED_AS, Recipe, resolve_recipes


def weights_sources(
        recipes: Sequence[Tuple[str, str]],
        rows: Optional[Dict[str, Recipe]] = None
) -> Dict[str, Optional[str]]:
    """Which recipe's weights each recipe tests (None: its own, trained).

    A set file's row with ``weights_of = NAME`` names an earlier row; a
    config with ``compare_weights_of = PATH`` names the config of an
    earlier recipe of ``recipes``; ``PATH`` is relative to the config's
    folder (or absolute).

    Args:
        recipes (Sequence[tuple[str, str]]): (name, config path), in order.
        rows (dict, optional): Recipe name -> its set file row
            (:func:`cbnet_lab.sets.set_rows`).

    Returns:
        dict: recipe name -> name of the recipe whose weights it tests.

    Raises:
        ValueError: ``PATH`` is not the config of an earlier recipe, or that
            recipe is itself a test-time variant.
    """
    sources, seen = {}, {}
    rows = rows or {}
    for name, config in recipes:
        target = read_config(config).get('compare_weights_of')
        row = rows.get(name)
        if row is not None and row.weights_of is not None:
            if sources.get(row.weights_of, 'missing') is not None:
                raise ValueError(
                    f'recipe {name!r} tests the weights of '
                    f'{row.weights_of!r}, which is not an earlier recipe of '
                    'this comparison that trains (give it too, before '
                    f'{name!r})')
            sources[name] = row.weights_of
        elif target is None:
            sources[name] = None
        else:
            path = osp.realpath(
                osp.join(osp.dirname(osp.abspath(config)), target))
            source = seen.get(path)
            if source is None or sources[source] is not None:
                raise ValueError(
                    f'recipe {name!r} tests the weights of {path} '
                    '(compare_weights_of), but no earlier recipe of the '
                    'comparison trains that config: list it before '
                    f'{name!r}')
            sources[name] = source
        seen.setdefault(osp.realpath(config), name)
    return sources


def trained_as(set_name: Optional[str],
               recipes: Sequence[Tuple[str, str]]) -> Dict[str, str]:
    """Which of ``recipes`` train exactly as a row of another set.

    Args:
        set_name (str, optional): The comparison's set
            (:data:`cbnet_lab.sets.SET_TRAINED_AS`).
        recipes (Sequence[tuple[str, str]]): (name, config path).

    Returns:
        dict: recipe name -> the other set's row name, for the recipes of
        ``recipes`` that the set names.

    Raises:
        ValueError: The set has no such rows, or a row's config differs
            from the other row's in more than its ``transfer_*`` /
            ``compare_*`` keys: training one would not be training the
            other.
    """
    spec = SET_TRAINED_AS.get(set_name)
    if spec is None:
        raise ValueError(
            f'no row of the set {set_name!r} trains as another set\'s '
            '(--weights-from is for ' + ', '.join(sorted(SET_TRAINED_AS)) +
            ')')

    def training_keys(config: str) -> dict:
        return {k: v for k, v in read_config(config).to_dict().items()
                if not k.startswith(('transfer_', 'compare_'))}

    theirs = dict(resolve_recipes(spec['set']))
    found = {}
    for name, config in recipes:
        other = spec['rows'].get(name)
        if other is None:
            continue
        mine, its = training_keys(config), training_keys(theirs[other])
        differ = sorted(k for k in set(mine) | set(its)
                        if mine.get(k) != its.get(k))
        if differ:
            raise ValueError(
                f'recipe {name!r} should train as the {spec["set"]} set\'s '
                f'{other!r}, but their configs differ in {differ} (only '
                'transfer_* and compare_* keys may)')
        found[name] = other
    return found


def reference_condition(recipes: Sequence[Tuple[str, str]]) -> str:
    """The condition every recipe is tested on first: ``'clear'``, or the
    ``test_condition`` all the recipes' configs name (real data).

    Raises:
        ValueError: The recipes name different conditions.
    """
    names = {name: test_condition(read_config(config)) or 'clear'
             for name, config in recipes}
    if len(set(names.values())) > 1:
        raise ValueError(
            'the recipes are tested on different data (test_condition of '
            f'each: {names}); compare recipes of one kind at a time')
    return next(iter(names.values()))


def check_data(reference: str, data_root: str,
               betas: Sequence[float]) -> None:
    """Clear errors before any training: real data (``reference`` other
    than ``'clear'``) must exist and takes no betas; generated or
    Cityscapes data must have its converted val annotations."""
    if reference != 'clear':
        if not osp.isdir(data_root):
            raise FileNotFoundError(
                f'--data-root {data_root} not found: the recipes test real '
                f'data ({reference!r}); give its folder')
        if betas:
            raise ValueError(
                f'the recipes test real data ({reference!r}): no foggy '
                f'betas apply, got {list(betas)}')
        return
    ann = osp.join(data_root, 'annotations',
                   'instancesonly_filtered_gtFine_val.json')
    if not osp.isfile(ann):
        raise FileNotFoundError(
            f'{ann} not found: --data-root must be a dataset in the '
            'Cityscapes layout with converted annotations (generate one '
            'with `python tools/misc/generate_cityscapes_like.py DIR '
            '--convert`, or convert the real one with '
            '`python tools/dataset_converters/cityscapes.py DIR`)')


def check_transfer(recipes: Sequence[Tuple[str, str]],
                   transfer_root: Optional[str]) -> None:
    """The real-fog folder of the recipes' ``transfer_test`` exists, before
    any training (each config's own ``data_root`` when ``transfer_root``
    is None); ``transfer_root`` without such a recipe is an error."""
    specs = {name: transfer_test(read_config(config))
             for name, config in recipes}
    if transfer_root is not None and not any(specs.values()):
        raise ValueError(
            f'--transfer-root {transfer_root}: no recipe sets transfer_test '
            '(a second test set), so it would not be read')
    for name, spec in specs.items():
        root = transfer_root or (spec or {}).get('data_root')
        if spec is not None and not osp.isdir(root):
            raise FileNotFoundError(
                f'recipe {name!r} is also tested on {spec["condition"]!r}, '
                f'the VOC folder {root}, which does not exist; give it with '
                '--transfer-root')


def check_pretrained(recipes: Sequence[Tuple[str, str]],
                     sources: Dict[str, Optional[str]]) -> None:
    """Every pretrained file the trained recipes load, before the first
    run (not hours later): a missing one is an error naming the command
    that fetches it (:func:`cbnet_tools.pretrained
    .require_pretrained`). Test-time variants load no trunk."""
    for name, config in recipes:
        if sources[name] is None:
            require_pretrained(read_config(config))
