"""What the edge router's offloading is worth: offload rate vs AP.

The router (:mod:`.router`) keeps a frame on the light local model or sends
it to the server. Two runs of ``projects/edge_serving/tools/route.py``
over the same frames hold everything needed to score ANY threshold
offline, with the router's own :func:`.router.decide`:

* ``--mode local``: every frame's local prediction, its haze estimate
  (mean dark-channel transmission) and the local top score;
* ``--mode server``: every frame's server prediction (the same haze
  estimate and local score: the router always runs the local model first).

For a policy (``transmission_thr``, ``min_confidence``) a frame's result is
the server's when :func:`decide` offloads it, the local one otherwise; the
stream of results is scored with MMDet's ``CocoMetric`` against the
frames' ground truth (COCO instances file of the clear images: a foggy
frame ``{stem}_leftImg8bit_foggy_beta_{b}.png`` takes the annotations of
``{stem}_leftImg8bit.png``). Each frame is one image of the stream, so the
same scene under four fog densities counts four times. A run of
``--mode auto`` is scored as it was routed, to check that the live router
lands on the offline curve.

A random-offload control (the same number of frames, chosen at random) at
each rate says whether the haze estimate picks the frames where the server
helps more than chance does.
"""
import json
import os
import os.path as osp
import tempfile
from typing import Dict, List, Optional, Sequence

import numpy as np

from cbnet_mmdet.datasets.cityscapes_paths import split_beta
from cbnet_tools.markdown import markdown_table
from .router import RouterConfig, decide

#: Columns of the offload table: (key in a row, header).
COLUMNS = (('policy', 'policy'), ('offload_rate', 'offloaded'),
           ('bbox_mAP', 'box AP'), ('bbox_mAP_50', 'box AP50'),
           ('segm_mAP', 'mask AP'), ('segm_mAP_50', 'mask AP50'),
           ('seconds', 'mean s/frame'))


#: The AP keys of CocoMetric per metric (``bbox_mAP``, ...).
AP_KEYS = ('mAP', 'mAP_50', 'mAP_75', 'mAP_s', 'mAP_m', 'mAP_l')


def read_run(out_dir: str) -> Dict:
    """``route.py``'s output folder: ``{'records': {frame: record},
    'info': run.json or {}}``; clear errors for a missing or broken run."""
    path = osp.join(out_dir, 'results.jsonl')
    if not osp.isfile(path):
        raise FileNotFoundError(
            f'{path} not found: run projects/edge_serving/tools/route.py '
            f'--out-dir {out_dir} first')
    records = {}
    with open(path) as f:
        for n, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError as err:
                raise ValueError(f'{path}:{n}: not JSON ({err}); was the '
                                 'run killed while writing?') from None
            if rec['frame'] in records:
                raise ValueError(f"{path}:{n}: frame {rec['frame']!r} twice")
            records[rec['frame']] = rec
    if not records:
        raise ValueError(f'{path} has no frames')
    info_path = osp.join(out_dir, 'run.json')
    info = {}
    if osp.isfile(info_path):
        with open(info_path) as f:
            info = json.load(f)
    return dict(records=records, info=info, out_dir=out_dir)


def _classes(run: Dict, side: str, default: Optional[Sequence[str]]):
    got = (run['info'].get(side) or {}).get('classes')
    if got:
        return list(got)
    if default is None:
        raise ValueError(
            f"{run['out_dir']}/run.json does not name the {side} model's "
            'classes; pass classes= (the order of its labels)')
    return list(default)


def check_runs(local: Dict, server: Dict) -> List[str]:
    """The frames of two runs, after checking that they are comparable:
    same frames, same local model (equal haze estimate and top score),
    and a server answer for every frame of the server run."""
    lf, sf = set(local['records']), set(server['records'])
    if lf != sf:
        only = sorted(lf ^ sf)[:5]
        raise ValueError(f'the local and server runs hold different frames '
                         f'({len(lf)} vs {len(sf)}; e.g. {only})')
    frames = sorted(lf)
    fallback = [f for f in frames
                if server['records'][f]['where'] != 'server']
    if fallback:
        raise ValueError(
            f"{len(fallback)} frames of the server run were not answered by "
            f"the server (e.g. {fallback[0]!r}: "
            f"{server['records'][fallback[0]]['reason']}); rerun it")
    for f in frames:
        a, b = local['records'][f], server['records'][f]
        if (abs(a['transmission'] - b['transmission']) > 1e-6
                or abs(a['local_top_score'] - b['local_top_score']) > 1e-4):
            raise ValueError(
                f'frame {f!r}: the two runs disagree on the haze estimate '
                f"or the local top score ({a['transmission']:.6f} vs "
                f"{b['transmission']:.6f}, {a['local_top_score']:.4f} vs "
                f"{b['local_top_score']:.4f}): different local models?")
    return frames


#: How a frame's condition is read from its name (route.py's frame names
#: are paths relative to its input folder): ``'beta'``, the Foggy
#: Cityscapes file names (``*_foggy_beta_{b}.png`` -> ``b``, others
#: ``clear``; a frame takes its clear twin's annotations); ``'folder'``,
#: the first folder of the path (``fog/x.jpg`` -> ``fog``; a frame takes
#: the annotations of the image whose ``file_name`` is its path, as
#: :func:`.stream.build_stream` writes them).
CONDITION_RULES = ('beta', 'folder')


def frame_condition(frame: str, rule: str = 'beta') -> str:
    """The condition of a frame under ``rule`` (:data:`CONDITION_RULES`)."""
    if rule == 'beta':
        return split_beta(osp.basename(frame))[1]
    if rule == 'folder':
        parts = frame.replace(osp.sep, '/').split('/')
        if len(parts) < 2 or not parts[0]:
            raise ValueError(f'frame {frame!r} is in no folder: with '
                             "conditions='folder' each frame sits in its "
                             "condition's folder (e.g. fog/x.jpg)")
        return parts[0]
    raise ValueError(f'conditions={rule!r}: one of {CONDITION_RULES}')


def condition_order(conditions) -> List[str]:
    """``clear`` first, then fog densities by beta, then other names."""
    def key(c):
        try:
            return (c != 'clear', 0, float(c), c)
        except ValueError:
            return (c != 'clear', 1, 0.0, c)
    return sorted(set(conditions), key=key)


def stream_annotations(ann_file: str, frames: Sequence[str],
                       rule: str = 'beta') -> Dict:
    """A COCO instances dict with one image per frame (ids from 1, as
    pycocotools reads id 0 as "no match"), each holding the annotations of
    the image the frame shows: its clear twin (``rule='beta'``) or the
    image whose ``file_name`` is the frame's path (``'folder'``)."""
    if rule not in CONDITION_RULES:
        raise ValueError(f'conditions={rule!r}: one of {CONDITION_RULES}')
    with open(ann_file) as f:
        coco = json.load(f)
    by_name = {}
    for img in coco['images']:
        name = osp.basename(img['file_name']) if rule == 'beta' else \
            img['file_name'].replace(osp.sep, '/')
        by_name.setdefault(name, []).append(img)
    anns = {}
    for ann in coco['annotations']:
        anns.setdefault(ann['image_id'], []).append(ann)
    images, annotations, missing = [], [], []
    for i, frame in enumerate(frames, 1):
        key = split_beta(osp.basename(frame))[0] if rule == 'beta' else \
            frame.replace(osp.sep, '/')
        found = by_name.get(key, [])
        if len(found) != 1:
            missing.append(frame)
            continue
        img = dict(found[0], id=i, file_name=frame)
        images.append(img)
        for ann in anns.get(found[0]['id'], []):
            annotations.append(
                dict(ann, id=len(annotations) + 1, image_id=i))
    if missing:
        raise ValueError(
            f'{len(missing)} frames have no (or no single) image in '
            f'{ann_file}, e.g. {missing[:3]}: the frames must be the '
            "annotation file's images or their *_foggy_beta_* twins"
            if rule == 'beta' else
            f'{ann_file}, e.g. {missing[:3]}: each frame path must be an '
            "image's file_name (projects/edge_serving/tools/"
            'make_stream.py writes both)')
    return dict(coco, images=images, annotations=annotations)


def score(gt: Dict, predictions: Sequence[Dict], classes: Sequence,
          metrics: Sequence[str] = ('bbox', 'segm')) -> Dict[str, float]:
    """COCO AP of one prediction per image of ``gt`` (in its image order;
    ``pred2dict`` fields, masks as RLE) with MMDet's ``CocoMetric``.

    ``classes`` is a list per prediction or one list for all: the class
    names of the model that made it (its ``labels`` index them)."""
    import torch
    from mmdet.evaluation import CocoMetric

    if len(predictions) != len(gt['images']):
        raise ValueError(f"{len(predictions)} predictions for "
                         f"{len(gt['images'])} images")
    names = [c['name'] for c in gt['categories']]
    with tempfile.TemporaryDirectory() as tmp:
        ann = osp.join(tmp, 'stream.json')
        with open(ann, 'w') as f:
            json.dump(gt, f)
        metric = CocoMetric(ann_file=ann, metric=list(metrics))
        metric.dataset_meta = dict(classes=names)
        for i, (img, pred) in enumerate(zip(gt['images'], predictions)):
            own = classes[i] if isinstance(classes[0], (list, tuple)) \
                else classes
            labels = []
            for label in pred.get('labels', []):
                if own[label] not in names:
                    raise ValueError(f'class {own[label]!r} of a prediction '
                                     f'is not in the annotations ({names})')
                labels.append(names.index(own[label]))
            inst = dict(
                bboxes=torch.tensor(pred.get('bboxes', []),
                                    dtype=torch.float32).reshape(-1, 4),
                scores=torch.tensor(pred.get('scores', []),
                                    dtype=torch.float32),
                labels=torch.tensor(labels, dtype=torch.long))
            if 'segm' in metrics:
                masks = pred.get('masks')
                if masks is None:
                    raise ValueError(
                        f"prediction for {img['file_name']!r} has no masks; "
                        "score boxes only (metrics=('bbox',))")
                inst['masks'] = masks
            metric.process({}, [dict(img_id=img['id'],
                                     ori_shape=(img['height'], img['width']),
                                     pred_instances=inst)])
        out = metric.evaluate(len(predictions))
    out = {k.split('/')[-1]: 100 * v for k, v in out.items()}
    # CocoMetric reports nothing when no image has a detection: AP 0
    for m in metrics:
        for k in AP_KEYS:
            out.setdefault(f'{m}_{k}', 0.0)
    return out


def policy_offloads(records: Dict, frames: Sequence[str],
                    transmission_thr: float,
                    min_confidence: float) -> np.ndarray:
    """Which frames the router (:func:`decide`, mode ``auto``) offloads."""
    cfg = RouterConfig(transmission_thr=transmission_thr,
                       min_confidence=min_confidence, mode='auto')
    return np.array([
        decide(cfg, records[f]['transmission'], records[f]['local_top_score'])
        is not None for f in frames
    ])


def offload_curve(local_dir: str,
                  server_dir: str,
                  ann_file: str,
                  thresholds: Optional[Sequence[float]] = None,
                  confidences: Optional[Sequence[float]] = None,
                  policy: Optional[Dict] = None,
                  auto_dir: Optional[str] = None,
                  random_seeds: Sequence[int] = (0, 1, 2),
                  classes: Optional[Sequence[str]] = None,
                  metrics: Sequence[str] = ('bbox', 'segm'),
                  calibrate: bool = False,
                  conditions: str = 'beta',
                  progress=print) -> Dict:
    """Score always-local, always-server, the haze rule at each
    ``thresholds`` (``min_confidence`` 0; default: the deciles of the
    frames' transmission), the confidence rule at each ``confidences``
    (offload when the local top score is below; no haze rule; default:
    the deciles of the local top scores), the shipped ``policy``
    (``transmission_thr``, ``min_confidence``: both rules), random
    offloading at the same rates, and optionally a live ``--mode auto``
    run.

    Every row has ``rule`` (``local``, ``haze``, ``confidence``,
    ``shipped``, ``server``, ``random``, ``auto``); rows at default
    thresholds also ``quantile`` (the decile the threshold is), so that
    runs of several local models line up (:mod:`.offload_seeds`); a row
    that offloads some frames but not all has ``random``: the AP keys of
    random offloading of as many frames (mean of ``random_seeds``).

    ``conditions``: how a frame's condition (and its annotations) is
    found, :data:`CONDITION_RULES`.

    ``calibrate``: score every row with each model's scores mapped onto
    the precision they stand for (:mod:`.calibration`, cross-fitted on
    two halves of the frames), so that one ranking of the two models'
    detections means the same for both; the record keeps the maps.

    Returns ``{'frames', 'conditions', 'rows', 'by_condition'}``; a row
    has ``policy``, ``offload_rate``, ``offloaded`` per condition, the
    AP keys of :func:`score` on the whole stream, ``condition_ap`` (the
    same keys on each condition's frames alone) and ``seconds`` (mean per
    frame: the local run's time of a kept frame, the server run's of an
    offloaded one)."""
    if calibrate and auto_dir is not None:
        raise ValueError('a live auto run is scored as routed, with its '
                         'own scores: leave out auto_dir or calibrate')
    local, server = read_run(local_dir), read_run(server_dir)
    frames = check_runs(local, server)
    rule = conditions
    gt = stream_annotations(ann_file, frames, rule)
    local_cls = _classes(local, 'local', classes)
    server_cls = _classes(server, 'server', classes)
    cond = [frame_condition(f, rule) for f in frames]
    conditions = condition_order(cond)
    # each model's prediction per frame (its scores calibrated on request)
    stream = {side: [run['records'][f]['prediction'] for f in frames]
              for side, run in (('local', local), ('server', server))}
    calibration = None
    if calibrate:
        from .calibration import cross_fitted
        calibration = {}
        for side, cls in (('local', local_cls), ('server', server_cls)):
            progress(f'calibrating the {side} model\'s scores')
            stream[side], calibration[side] = cross_fitted(
                stream[side], gt, cls)
    t = np.array([local['records'][f]['transmission'] for f in frames])
    top = np.array([local['records'][f]['local_top_score']
                    for f in frames], float)
    haze_levels = _levels(t, thresholds)
    conf_levels = _levels(top, confidences)

    # each condition's frames and their ground truth, once
    members = {c: [i for i, k in enumerate(cond) if k == c]
               for c in conditions}
    subsets = {}
    for c, keep in members.items():
        ids = {gt['images'][i]['id'] for i in keep}
        subsets[c] = dict(
            gt, images=[gt['images'][i] for i in keep],
            annotations=[a for a in gt['annotations']
                         if a['image_id'] in ids])

    def row(name, offload, preds=None, per_class=None, seconds=None,
            rule=None, quantile=None):
        offload = np.asarray(offload, bool)
        if preds is None:
            preds = [stream['server'][i] if o else stream['local'][i]
                     for i, o in enumerate(offload)]
            per_class = [server_cls if o else local_cls for o in offload]
            seconds = [server['records'][f]['seconds'] if o else
                       local['records'][f]['seconds']
                       for f, o in zip(frames, offload)]
        progress(f'scoring {name} ({offload.mean():.0%} offloaded)')
        by = {c: float(np.mean(offload[keep]))
              for c, keep in members.items()}
        per_cond = {
            c: score(subsets[c], [preds[i] for i in keep],
                     [per_class[i] for i in keep], metrics)
            for c, keep in members.items()}
        extra = {} if quantile is None else dict(quantile=quantile)
        return dict(policy=name, rule=rule, **extra,
                    offload_rate=float(offload.mean()),
                    offloaded=by, seconds=float(np.mean(seconds)),
                    condition_ap=per_cond,
                    **score(gt, preds, per_class, metrics))

    n = len(frames)
    rows = [row('always local', np.zeros(n), rule='local')]
    for thr, q in haze_levels:
        rows.append(row(f'haze: transmission < {thr:g}',
                        policy_offloads(local['records'], frames, thr, 0.0),
                        rule='haze', quantile=q))
    for conf, q in conf_levels:
        # transmission_thr 0: no frame is hazier than that, only the
        # local model's confidence decides
        rows.append(row(f'confidence: top score < {conf:g}',
                        policy_offloads(local['records'], frames, 0.0, conf),
                        rule='confidence', quantile=q))
    if policy is not None:
        rows.append(row(
            f"shipped: transmission < {policy['transmission_thr']:g} or "
            f"top score < {policy['min_confidence']:g}",
            policy_offloads(local['records'], frames,
                            policy['transmission_thr'],
                            policy['min_confidence']), rule='shipped'))
    server_only = row('always server', np.ones(n), rule='server')
    rows.append(server_only)
    # random offloading at each rate a rule reached
    policies = list(rows)
    random_at = {}
    for count in sorted({int(r['offload_rate'] * n + 0.5) for r in rows}
                        - {0, n}):
        runs = []
        for seed in random_seeds:
            pick = np.zeros(n, bool)
            pick[np.random.default_rng(seed).choice(n, count,
                                                    replace=False)] = True
            runs.append(row(f'random {count}/{n} (seed {seed})', pick))
        mean = {k: float(np.mean([r[k] for r in runs])) for k in runs[0]
                if isinstance(runs[0][k], float)}
        mean['offloaded'] = {c: float(np.mean([r['offloaded'][c]
                                               for r in runs]))
                             for c in conditions}
        mean['condition_ap'] = {
            c: {k: float(np.mean([r['condition_ap'][c][k] for r in runs]))
                for k in runs[0]['condition_ap'][c]}
            for c in conditions}
        mean['policy'] = (f'random {count}/{n} (mean of '
                          f'{len(runs)} seeds)')
        mean['rule'] = 'random'
        mean['std'] = {k: float(np.std([r[k] for r in runs]))
                       for k in ('bbox_mAP', 'segm_mAP') if k in runs[0]}
        rows.append(mean)
        random_at[count] = mean
    for r in policies:
        count = int(r['offload_rate'] * n + 0.5)
        if count in random_at:
            r['random'] = {k: v for k, v in random_at[count].items()
                           if k.startswith(('bbox_', 'segm_'))}
    if auto_dir is not None:
        auto = read_run(auto_dir)
        missing = sorted(set(frames) - set(auto['records']))
        if missing:
            raise ValueError(f'the auto run lacks {len(missing)} frames, '
                             f'e.g. {missing[:3]}')
        recs = [auto['records'][f] for f in frames]
        auto_cls = _classes(auto, 'local', classes)
        rows.append(row(
            'live auto run (route.py --mode auto)',
            [r['where'] == 'server' for r in recs],
            preds=[r['prediction'] for r in recs],
            per_class=[_classes(auto, 'server', classes)
                       if r['where'] == 'server' else auto_cls
                       for r in recs],
            seconds=[r['seconds'] for r in recs], rule='auto'))
        rows[-1]['fallbacks'] = sum(r['where'] == 'local-fallback'
                                    for r in recs)
    # each model alone per condition: the always-local and always-server
    # rows' scores on that condition's frames
    by_condition = {c: dict(local=rows[0]['condition_ap'][c],
                            server=server_only['condition_ap'][c])
                    for c in conditions}
    return dict(frames=n, conditions=conditions, rows=rows,
                by_condition=by_condition, calibrated=bool(calibrate),
                condition_rule=rule,
                calibration=calibration,
                transmission={c: float(np.mean(t[keep]))
                              for c, keep in members.items()})


def _levels(values: np.ndarray, given: Optional[Sequence[float]]):
    """``(threshold, quantile)`` pairs: ``given`` thresholds (quantile
    None), or the deciles of ``values`` (rounded to 4 places; a threshold
    two deciles share is kept once, with the lower decile)."""
    if given is not None:
        return [(float(v), None) for v in given]
    out = {}
    for q in np.round(np.linspace(0.1, 0.9, 9), 1).tolist():
        out.setdefault(round(float(np.quantile(values, q)), 4), q)
    return sorted(out.items())


def to_markdown(result: Dict) -> str:
    """The offload table (one row per policy) and the per-condition AP of
    the two models."""
    conds = result['conditions']
    keys = [(k, h) for k, h in COLUMNS
            if k in ('policy', 'offload_rate', 'seconds')
            or k in result['rows'][0]]
    # box AP on each condition's frames alone (records before the
    # per-condition rows have none)
    by_cond = all('condition_ap' in r for r in result['rows'])
    head = [h for _, h in keys[:2]] + [f'offloaded {c}' for c in conds] + \
        [h for _, h in keys[2:]] + \
        ([f'box AP {c}' for c in conds] if by_cond else []) + \
        ['box AP, random at that rate']
    rows = []
    for r in result['rows']:
        cells = [r['policy'], f"{r['offload_rate']:.0%}"]
        cells += [f"{r['offloaded'][c]:.0%}" for c in conds]
        for k, _ in keys[2:]:
            v = f'{r[k]:.3f}' if k == 'seconds' else f'{r[k]:.1f}'
            if k in r.get('std', {}):
                v += f" +- {r['std'][k]:.1f}"
            cells.append(v)
        if by_cond:
            cells += [f"{r['condition_ap'][c]['bbox_mAP']:.1f}"
                      for c in conds]
        cells.append(f"{r['random']['bbox_mAP']:.1f}" if 'random' in r
                     else '')
        rows.append(cells)
    lines = (['Scores calibrated per model (cross-fitted isotonic '
              'score -> precision maps).', ''] if result.get('calibrated')
             else []) + markdown_table(head, rows) + ['']
    rows = []
    for c in conds:
        cells = [c, f"{result['transmission'][c]:.3f}"]
        for side in ('local', 'server'):
            cells += [f"{result['by_condition'][c][side][k]:.1f}"
                      for k, _ in keys[2:] if k != 'seconds']
        rows.append(cells)
    lines += markdown_table(
        ['condition', 'mean transmission'] +
        [f'{side} {h}' for side in ('local', 'server')
         for k, h in keys[2:] if k != 'seconds'], rows)
    return '\n'.join(lines) + '\n'


def write(result: Dict, out_dir: str) -> Dict[str, str]:
    """``offload.json`` and ``offload.md`` under ``out_dir``."""
    os.makedirs(out_dir, exist_ok=True)
    paths = dict(json=osp.join(out_dir, 'offload.json'),
                 markdown=osp.join(out_dir, 'offload.md'))
    with open(paths['json'], 'w') as f:
        json.dump(result, f, indent=1)
    with open(paths['markdown'], 'w') as f:
        f.write(to_markdown(result))
    return paths
