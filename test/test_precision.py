"""The precision against a lab's target (estimation.precision): half-widths on the entries'
scales, the entries short of the target, and the length offered only where σ is the noise's.
The length law itself is tested on simulated rigs in test_any_rig; the package's claims against
the truth over many rigs are bench/bench_any_rig.py's."""
import numpy as np
import pytest

from rig_identification.estimation.precision import Z95, precision_of
from rig_identification.io.verdict import KEYS
from rig_identification.model.parametrisation import to_tensor

# a 1.4 t car's tensor (kg·m²; entries ixx, ixy, ixz, iyy, iyz, izz) and σ making Ixx ±2.5 %,
# Ixz ±0.63 % of the largest moment, the rest narrower
THETA = np.array([500.0, 0.0, -50.0, 1500.0, 0.0, 1600.0])
STD = np.array([6.3, 1.0, 5.1, 4.0, 3.0, 2.0])


def test_half_widths_are_on_each_entrys_scale_and_the_short_ones_are_named():
    p = precision_of(to_tensor(THETA), STD, (), 120.0, "ok")
    scale = np.array([500.0, 1600.0, 1600.0, 1500.0, 1600.0, 1600.0])
    np.testing.assert_allclose([p.half_width[k] for k in KEYS], Z95 * STD / scale, rtol=1e-12)
    assert p.short == ("ixx",) and not p.met and p.noise_limited
    # σ ∝ 1/√T: the length that brings Ixx's 1.96 σ to 1 % of 500 kg·m²
    assert p.length_factor == pytest.approx((Z95 * 6.3 / 500.0 / 0.01) ** 2, rel=1e-12)
    assert "Ixx ±2.5 %: short of the target" in p.text() and f"({p.length_factor * 120:.0f} s)" in p.text()
    assert precision_of(to_tensor(THETA), STD, (), 120.0, "ok", target=0.03).met


def test_no_length_where_sigma_is_not_the_noises():
    for verdict, words in (("model_error", "a longer recording does not reach it"),
                           ("not_identifiable", "first what the verdict's advice says"),
                           (None, "no model validation")):
        p = precision_of(to_tensor(THETA), STD, (), 120.0, verdict)
        assert p.short == ("ixx",) and p.length_factor is None and words in p.text()
    # only the widening beyond the propagated noise is short: no length, and said so
    p = precision_of(to_tensor(THETA), STD, (), 120.0, "ok", noise_std=STD / 3)
    assert p.short == ("ixx",) and p.length_factor is None and p.widened_only and "widened" in p.text()


def test_undetermined_entries_are_left_out():
    p = precision_of(to_tensor(THETA), STD, ("ixx", "ixy", "ixz"), 120.0, "not_identifiable")
    assert p.half_width["ixx"] is None and p.met and p.text().endswith("(the widest: Iyy ±0.52 %)"), p.text()
    assert precision_of(to_tensor(np.full(6, np.nan)), STD, KEYS, 60.0, "not_identifiable").text().endswith(
        "no entry is determined")
    with pytest.raises(ValueError, match="positive"):
        precision_of(to_tensor(THETA), STD, (), 120.0, "ok", target=0.0)
