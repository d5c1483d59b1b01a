"""The one reading of a comparison record (``runs`` of ``recipe`` /
``seed`` / ``config`` / ``metrics``) shared by the tests that check the
docs' and the metafiles' figures against the records: grouped here from
the raw runs, never from a summary the record may also hold."""


def seed_values(record, config=None):
    """``(recipe, condition, metric) -> [(seed, value in percent), ...]``
    over the runs of a comparison record, in run order; with ``config``,
    only the runs whose config path ends with it. Anything that is not a
    comparison record gives ``{}``; non-numeric metric values are left
    out."""
    runs = record.get('runs') if isinstance(record, dict) else None
    groups = {}
    for run in runs if isinstance(runs, list) else []:
        path = str(run.get('config', ''))
        if config is not None and not path.endswith(config):
            continue
        for condition, metrics in (run.get('metrics') or {}).items():
            for key, value in metrics.items():
                if isinstance(value, (int, float)) and not isinstance(
                        value, bool):
                    groups.setdefault((run['recipe'], condition, key),
                                      []).append((run['seed'], 100 * value))
    return groups
