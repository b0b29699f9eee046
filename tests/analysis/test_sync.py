"""Clock alignment: resampling with gaps, event offsets, and cross-correlation on real data."""

from __future__ import annotations

import numpy as np
import pytest

from app.analysis.emg import emg_envelope
from app.analysis.pose import arm_angles
from app.analysis.sync import estimate_offset, event_offset, resample
from tests.analysis._data import pyomeca_c3d


def test_resample_is_exact_for_lines_and_keeps_gaps() -> None:
    ts = np.arange(10.0)
    x = np.column_stack([2 * ts + 1, -ts])
    x[5, 0] = np.nan
    tt = np.array([-1.0, 0.0, 2.5, 4.0, 4.5, 6.0, 9.0, 9.5])
    got = resample(ts, x, tt)
    np.testing.assert_allclose(got[:, 1], [np.nan, 0, -2.5, -4, -4.5, -6, -9, np.nan])
    np.testing.assert_allclose(got[:, 0], [np.nan, 1, 6, 9, np.nan, 13, 19, np.nan])


def test_event_offset_sign_convention() -> None:
    # A tap at 12.0 s on the EMG clock and 2.0 s on the video clock: t_emg = t_pose + 10.
    assert event_offset(12.0, 2.0) == 10.0


def test_estimate_offset_recovers_a_synthetic_shift() -> None:
    rate_emg, rate_pose = 1000.0, 50.0
    te = np.arange(int(30 * rate_emg)) / rate_emg
    env = np.zeros_like(te)
    for c in (4.0, 9.0, 13.0, 19.5, 24.0):
        env += np.exp(-(((te - c) / 0.3) ** 2))
    true = 0.37
    tp = np.arange(int(25 * rate_pose)) / rate_pose  # pose clock
    kin = np.interp(tp + true, te, env) + 0.05 * np.random.default_rng(0).standard_normal(len(tp))
    kin[100:140] = np.nan  # a gap in the pose
    assert estimate_offset(env, rate_emg, kin, tp, max_lag=1.0) == pytest.approx(true, abs=0.01)


def test_estimate_offset_on_real_synchronised_emg_and_markers() -> None:
    # The C3D holds EMG and markers on one clock. Relabel the pose clock by -shift: the estimate
    # must follow the shift exactly, and its bias is the electromechanical delay (EMG leads the
    # elbow's acceleration by a few tens of ms, so the estimate sits slightly below the shift).
    rec = pyomeca_c3d()
    angles = arm_angles(rec)
    emg = rec.of_kind("emg")
    x = np.stack([c.data for c in emg], axis=1)
    env = emg_envelope(x, emg[0].rate)
    acc = np.abs(angles.elbow_acceleration)
    shifts = np.array([-0.4, -0.3, 0.0, 0.2, 0.4])
    got = np.array([estimate_offset(env, emg[0].rate, acc, angles.t - s) for s in shifts])
    bias = got - shifts
    np.testing.assert_allclose(bias, bias[0], atol=0.01)
    assert -0.1 < bias[0] < 0.0
