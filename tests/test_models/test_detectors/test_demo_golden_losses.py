"""Golden loss dict of the whole demo CBNet (seeded, CPU): any silent
change of the forward logic (backbone, neck, Cascade RPN, cascade heads,
mask loss) fails here. Regenerate deliberately changed values with
``python tests/test_models/test_detectors/golden_demo_losses.py --update``
(see that file)."""
import pytest

from golden_demo_losses import GOLDEN, demo_losses


def test_demo_model_losses_match_golden_values():
    assert GOLDEN, 'GOLDEN is empty: run golden_demo_losses.py --update'
    losses = demo_losses()
    assert sorted(losses) == sorted(GOLDEN)
    mismatched = {
        key: (losses[key], value) for key, value in GOLDEN.items()
        if losses[key] != pytest.approx(value, rel=1e-4, abs=1e-4)
    }
    assert not mismatched, f'(got, golden): {mismatched}'
    # the batch exercises every stage: positive RoIs in all three
    assert all(GOLDEN[f's{i}.loss_bbox'] > 0 for i in range(3))
