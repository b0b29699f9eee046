"""Sessions, channel choices and the rate check, through the library calls the service uses:
separate trials keep their own clocks and lifts while the template pools them; a new muscle map
or excluded channels is just another call on the same recordings; an implausible stored EMG rate
comes back as data with the suggested rate."""

from __future__ import annotations

import pytest

from app.analysis import analyze_recordings
from app.recordings import RecordingError, rate_check, read_recording
from tests.analysis._data import noraxon_recording
from tests.conftest import shared_file

NT01 = "noraxon_curls_biceps_brachioradialis/NT-01.mat"


def test_separate_trials_keep_their_clocks_and_pool_the_template() -> None:
    nt, sp = noraxon_recording("NT-01"), noraxon_recording("SP-01")
    result = analyze_recordings([nt, sp])
    assert result.settings["session"] == "separate"
    a, b = result.recordings
    assert (a.source, b.source) == ("NT-01.mat", "SP-01.mat")
    assert len(a.lifts) == len(b.lifts) == 10
    # Each file on its own clock: both start near 0 s, not one after the other.
    assert a.lifts[0].lift.start < 10.0 and b.lifts[0].lift.start < 10.0
    assert result.template.emg_lifts == 20
    joined = analyze_recordings([nt, sp], together=True, offset=0.0)
    assert joined.settings["session"] == "together" and len(joined.recordings) == 1


def test_a_new_muscle_map_or_excluded_channel_is_another_call() -> None:
    rec = noraxon_recording("SP-01")
    first = analyze_recordings([rec])
    assert {m.muscle for m in first.recordings[0].emg} == {"biceps", "forearm"}
    remapped = analyze_recordings([rec], muscle_map={"Brachioradialis": "triceps"})
    assert {m.muscle for m in remapped.recordings[0].emg} == {"biceps", "triceps"}
    fewer = analyze_recordings([rec], exclude_channels=["brachioradialis"])
    assert [m.channel for m in fewer.recordings[0].emg] == ["BicepsBrachi"]
    assert fewer.settings["exclude_channels"] == ["brachioradialis"]
    # The recording itself is untouched by either call.
    assert set(rec.channels) == {"BicepsBrachi", "Brachioradialis"}
    with pytest.raises(RecordingError, match="cannot exclude channel 'deltoid'"):
        analyze_recordings([rec], exclude_channels=["deltoid"])


def test_the_stored_20_khz_of_nt01_comes_back_as_a_rate_check() -> None:
    rec = read_recording(shared_file(NT01))
    check = rate_check(rec)
    assert check is not None
    assert check.stored_rate == 20000.0 and check.suggested_rate == 2000.0
    assert check.median_frequency > 300.0 and "implausible" in check.reason
    analysis = analyze_recordings([rec]).recordings[0]
    assert analysis.rate_check == check
    assert analysis.to_dict()["rate_check"]["suggested_rate_hz"] == 2000.0
    fixed = read_recording(shared_file(NT01), emg_rate=check.suggested_rate)
    assert rate_check(fixed) is None
