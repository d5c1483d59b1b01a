"""Reporting of the lab (cbnet_lab/report.py): plots of a comparison and
the machine line."""
from cbnet_lab import recipe_comparison as rc
from cbnet_lab import report
from cbnet_lab.report import machine_info, machine_line


def fake_run(recipe, seed, clear, foggy, key='coco/segm_mAP'):
    return dict(recipe=recipe, seed=seed, train_time_s=10.0 + seed,
                metrics={'clear': {key: clear},
                         'foggy beta=0.02': {key: foggy}})


def spy(monkeypatch, method, arg=0):
    """Positional argument ``arg`` of every call of ``Axes.<method>`` (a
    label, bar heights...), in call order; the calls still draw."""
    import matplotlib.axes
    calls = []
    real = getattr(matplotlib.axes.Axes, method)

    def record(self, *args, **kwargs):
        calls.append(args[arg])
        return real(self, *args, **kwargs)

    monkeypatch.setattr(matplotlib.axes.Axes, method, record)
    return calls


def test_plot_draws_box_ap_when_a_recipe_has_no_masks(tmp_path, monkeypatch):
    runs = [fake_run('masks', 0, 0.3, 0.2),
            fake_run('boxes', 0, 0.4, 0.3, key='coco/bbox_mAP')]
    runs[0]['metrics']['clear']['coco/bbox_mAP'] = 0.35
    runs[0]['metrics']['foggy beta=0.02']['coco/bbox_mAP'] = 0.25
    labels = spy(monkeypatch, 'set_ylabel')
    report.plot(rc.summarize(runs, [0.02]), [0.02], str(tmp_path / 'p.png'))
    assert labels == ['box AP (%)']  # every recipe on the plot
    labels.clear()
    report.plot(rc.summarize(runs[:1], [0.02]), [0.02],
                str(tmp_path / 'q.png'))
    assert labels == ['mask AP (%)']


def test_plot_adds_bars_for_a_second_test_set(tmp_path, monkeypatch):
    """Fog densities and then real fog (generated -> real): the curve over
    clear and the densities, and bars on real fog beside it."""
    runs = [fake_run('A', s, 0.4, 0.3, key='coco/bbox_mAP')
            for s in range(2)]
    for run, ap in zip(runs, (0.01, 0.03)):
        run['metrics']['real fog'] = {'coco/bbox_mAP': ap}
    summary = rc.summarize(runs, [0.02])
    assert summary['conditions'][-1] == 'real fog'
    labels = spy(monkeypatch, 'set_ylabel')
    heights = spy(monkeypatch, 'bar', arg=1)  # bar(x, height)
    path = report.plot(summary, [0.02], str(tmp_path / 'p.png'))
    assert labels == ['box AP (%) on real fog', 'box AP (%)']
    # the mean of 1 and 3, percent
    assert [list(h) for h in heights] == [[2.0]]
    with open(path, 'rb') as f:
        assert f.read(8) == b'\x89PNG\r\n\x1a\n'
    # without the second test set: the curve alone
    labels.clear()
    for run in runs:
        del run['metrics']['real fog']
    report.plot(rc.summarize(runs, [0.02]), [0.02], str(tmp_path / 'q.png'))
    assert labels == ['box AP (%)']


def test_plot_writes_a_png(tmp_path, monkeypatch):
    runs = [fake_run('A', s, 0.3, 0.2) for s in range(2)]
    ticks = spy(monkeypatch, 'set_xticklabels')
    path = report.plot(rc.summarize(runs, [0.02]), [0.02],
                       str(tmp_path / 'p.png'))
    # the density axis is ticked at clear and the tested densities only
    assert [list(t) for t in ticks] == [['0', '0.02']]
    with open(path, 'rb') as f:
        assert f.read(8) == b'\x89PNG\r\n\x1a\n'


def test_machine_info_and_line_describe_this_run(monkeypatch):
    import os
    import platform

    import torch
    monkeypatch.setattr(os, 'getloadavg', lambda: (1.234, 0.5, 0.25))
    info = machine_info('cpu')
    assert info['cpu_count'] == os.cpu_count()
    assert info['threads'] == torch.get_num_threads()
    assert info['torch'] == torch.__version__
    assert info['loadavg'] == [1.23, 0.5, 0.25]
    assert info['device'].startswith('CPU ')
    line = machine_line(info)
    assert line.startswith(info['device'])
    assert f'torch {torch.__version__}' in line and platform.system() in line
    assert line.endswith('load 1.23 / 0.50 / 0.25')
    # on a GPU: its name, then the CPU that feeds it
    monkeypatch.setattr(torch.cuda, 'get_device_name',
                        lambda device=None: 'NVIDIA FakeGPU')
    gpu = machine_info('cuda:0')['device']
    assert gpu == 'NVIDIA FakeGPU + ' + info['device']
    assert machine_line(device='cuda').startswith('NVIDIA FakeGPU + CPU ')
    # the line describes the record it is given, not this machine
    assert 'OtherOS' in machine_line(dict(info, system='OtherOS'))

    def no_loadavg():
        raise OSError('no load average here')

    monkeypatch.setattr(os, 'getloadavg', no_loadavg)
    assert 'load' not in machine_line(machine_info('cpu'))
