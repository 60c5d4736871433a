"""The precision against a lab's target (estimation.precision): half-widths on the entries'
scales, the entries short of the target, and the run length that reaches it by the asymptotic
law σ ∝ 1/√T.  The package's claims against the truth over many rigs are bench/bench_any_rig.py's."""
import numpy as np
import pytest

from rig_identification.estimation.precision import precision_of
from rig_identification.io.verdict import KEYS, Z95
from rig_identification.model.parametrisation import to_tensor

# a 1.4 t car's tensor (kg·m²; entries ixx, ixy, ixz, iyy, iyz, izz) and σ making Ixx ±2.5 %,
# Ixz ±0.63 % of the largest moment, the rest narrower
THETA = np.array([500.0, 0.0, -50.0, 1500.0, 0.0, 1600.0])
STD = np.array([6.3, 1.0, 5.1, 4.0, 3.0, 2.0])


def test_half_widths_are_on_each_entrys_scale_and_the_short_ones_are_named():
    p = precision_of(to_tensor(THETA), STD, 120.0)
    scale = np.array([500.0, 1600.0, 1600.0, 1500.0, 1600.0, 1600.0])
    np.testing.assert_allclose([p.half_width[k] for k in KEYS], Z95 * STD / scale, rtol=1e-12)
    assert p.short == ("ixx",) and not p.met
    # σ ∝ 1/√T: the length that brings Ixx's 1.96 σ to 1 % of 500 kg·m²
    assert p.length_factor == pytest.approx((Z95 * 6.3 / 500.0 / 0.01) ** 2, rel=1e-12)
    assert "Ixx ±2.5 %: short of the target" in p.text() and f"({p.length_factor * 120:.0f} s)" in p.text()
    wide = precision_of(to_tensor(THETA), STD, 120.0, target=0.03)
    assert wide.met and wide.length_factor is None and wide.text().endswith("(the widest: Ixx ±2.5 %)"), wide.text()
    assert wide.to_dict()["short"] == [] and p.to_dict()["length_factor"] == p.length_factor


def test_a_bad_target_or_sigma_is_refused():
    with pytest.raises(ValueError, match="positive"):
        precision_of(to_tensor(THETA), STD, 120.0, target=0.0)
    with pytest.raises(ValueError, match="positive and finite"):
        precision_of(to_tensor(THETA), np.r_[STD[:5], np.inf], 120.0)
