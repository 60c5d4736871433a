"""The identifier's window rule (estimation.fit_window) on synthetic gap lists: the window asked
for, the settling time, a window edge cut at a gap, the data after the last gap, the refusals."""
import pytest

from rig_identification.estimation.fit_window import FitWindowError, WindowRequest, describe_gaps, fit_window

T0 = 1000.0


def gaps_of(spans):
    """gaps_in(lo, hi) of fixed gaps (stream, a, b) in stamps."""
    return lambda lo, hi: [g for g in spans if g[1] < hi and g[2] > lo]


def test_no_gap_window_from_settle_to_the_latest_sample():
    w = fit_window(T0, T0 + 120.0, gaps_of([]), WindowRequest(settle=5.0))
    assert (w.start, w.end, w.notes) == (T0 + 5.0, T0 + 120.0, ())
    w = fit_window(T0, T0 + 120.0, gaps_of([]), WindowRequest(2.0, 100.0, 30.0, settle=5.0))
    assert (w.start, w.end) == (T0 + 70.0, T0 + 100.0)   # the last 30 s of [5, 100] s


def test_without_a_window_the_fit_starts_after_the_last_gap_plus_settle_after_gap():
    gaps = [("/rig/load_cells/c1", T0 + 30.0, T0 + 42.0), ("/rig/exciter/wrench", T0 + 30.0, T0 + 42.5)]
    w = fit_window(T0, T0 + 120.0, gaps_of(gaps), WindowRequest(settle_after_gap=20.0))
    assert (w.start, w.end) == (T0 + 62.5, T0 + 120.0)
    assert len(w.notes) == 1 and "settle_after_gap 20 s" in w.notes[0]
    assert "/rig/load_cells/c1" in w.notes[0] and "/rig/exciter/wrench" in w.notes[0]
    # only the last N s asked (no start or end): the data after the gap too, the last N s of them
    w = fit_window(T0, T0 + 120.0, gaps_of(gaps), WindowRequest(last=100.0))
    assert (w.start, w.end) == (T0 + 42.5, T0 + 120.0)
    w = fit_window(T0, T0 + 120.0, gaps_of(gaps), WindowRequest(last=40.0))
    assert (w.start, w.end, w.notes) == (T0 + 80.0, T0 + 120.0, ())


def test_a_window_ending_inside_a_gap_is_cut_at_its_edge():
    gaps = [("/rig/imu", T0 + 90.0, T0 + 130.0)]
    w = fit_window(T0, T0 + 130.0, gaps_of(gaps), WindowRequest(10.0, 120.0))
    assert (w.start, w.end) == (T0 + 10.0, T0 + 90.0)
    assert w.notes == ("window end moved to t=90.00 s, where /rig/imu stops",)


def test_a_gap_inside_the_window_asked_for_is_refused_naming_it():
    gaps = [("/rig/imu", T0 + 50.0, T0 + 51.0)]
    with pytest.raises(FitWindowError, match=r"contains a gap: no data on /rig/imu from t=50.00 to 51.00 s"):
        fit_window(T0, T0 + 120.0, gaps_of(gaps), WindowRequest(10.0, 100.0))


def test_too_short_a_window_is_refused():
    with pytest.raises(FitWindowError, match="holds 3.0 s of data .*min_duration is 10 s"):
        fit_window(T0, T0 + 8.0, gaps_of([]), WindowRequest(settle=5.0))


def test_describe_gaps_lists_at_most_four():
    gaps = [("/rig/imu", T0 + k, T0 + k + 0.5) for k in range(6)]
    text = describe_gaps(gaps, T0)
    assert text.count("no data on") == 4 and "(and 2 more)" in text
