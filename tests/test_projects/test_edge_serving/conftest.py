"""``runs``: a local and a server run of fake route.py over the offload
stream of ``serving_helpers.py`` (the server predicts the ground truth on
every frame, the local model on the clear frames only) and its
annotation file."""
import json

import pytest
from serving_helpers import NONE, annotations, img_of, truth, write_run


@pytest.fixture
def runs(tmp_path):
    ann = tmp_path / 'ann.json'
    json.dump(annotations(), open(ann, 'w'))
    local = write_run(tmp_path / 'local', 'local',
                      lambda f: NONE if 'foggy' in f else truth(img_of(f)))
    server = write_run(tmp_path / 'server', 'server',
                       lambda f: truth(img_of(f)))
    return dict(ann=str(ann), local=local, server=server, tmp=tmp_path)
