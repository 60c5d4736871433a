"""Roll, pitch and yaw follow the vehicle, not the axes (issue 36, item 3): rig.yaml's
``body.vehicle`` says where the vehicle's front and top lie in the body frame; the SAE J670 and
ISO 8855 tensors are J' = R J Rᵀ with R from it, the words roll/pitch/yaw label the body moments
it names, and without it neither the words nor the vehicle axes are given.

Synthetic inputs only (a hand-made rig and tensor): each test takes well under a second."""
import re

import numpy as np
import pytest
import yaml
from conftest import run_cli

from rig_identification.cli.recordings import output_axes
from rig_identification.cli.text import principal_lines, tensor_table
from rig_identification.io.export import AxesError, axes_block, axes_for, convention_lines, express
from rig_identification.io.rig import RigError, dump_rig, load_rig, rig_from_dict
from rig_identification.io.vehicle import Vehicle, common_vehicle
from rig_identification.model.parametrisation import to_tensor
from rig_identification.report.mass import convention, mass_properties_of, moments_table, principal_html

# a tensor with every product non-zero and three different moments (kg·m²): the Jeep's size,
# lying along body y (its smallest moment about y)
J = np.array([[2894.0, 12.0, -31.0], [12.0, 695.0, -102.0], [-31.0, -102.0, 3101.0]])
STD = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])          # KEYS order: ixx ixy ixz iyy iyz izz
CG = np.array([0.1, 0.2, 0.3])
FRONT_Y = Vehicle("+y", "+z")
# the rotations written out by hand (rows: the vehicle axes in body coordinates) for front +y, top +z:
# the vehicle's left is top × front = z × y = -x
SAE_BY_HAND = np.array([[0.0, 1.0, 0.0],     # x forward = body +y
                        [1.0, 0.0, 0.0],     # y right = body +x
                        [0.0, 0.0, -1.0]])   # z down = body -z
ISO_BY_HAND = np.array([[0.0, 1.0, 0.0],     # x forward = body +y
                        [-1.0, 0.0, 0.0],    # y left = body -x
                        [0.0, 0.0, 1.0]])    # z up = body +z
WORDS = re.compile(r"\b(roll|pitch|yaw)", re.IGNORECASE)


def rig_dict(**body) -> dict:
    """A small valid rig.yaml mapping: 4 cables, CG at the origin, ``body`` fields added."""
    return {"gravity": 9.80665,
            "cables": [{"name": f"c{i}", "ceiling_anchor": [x, y, 0.0], "body_anchor": [x / 2, y / 2, 1.0],
                        "length": 2.0} for i, (x, y) in enumerate([(-2, -2), (2, -2), (-2, 2), (2, 2)])],
            "body": {"mass": 1810.0, "center_of_gravity": [0.0, 0.0, 0.0], **body},
            "imu": {"position": [0.0, 0.0, 0.0]}}


# --- rig.yaml body.vehicle ------------------------------------------------------------------------

def test_vehicle_is_read_kept_and_absent_by_default(tmp_path):
    plain = rig_from_dict(rig_dict(), "rig.yaml")
    assert plain.vehicle is None and "vehicle" not in plain.to_dict()["body"]
    rig = rig_from_dict(rig_dict(vehicle={"front": "+y", "top": "+z"}), "rig.yaml")
    assert rig.vehicle == FRONT_Y
    p = tmp_path / "rig.yaml"
    p.write_text(dump_rig(rig))
    assert yaml.safe_load(p.read_text())["body"]["vehicle"] == {"front": "+y", "top": "+z"}
    assert load_rig(p).vehicle == FRONT_Y
    # YAML's plain "-x" and a Unicode minus are the same axis
    assert rig_from_dict(rig_dict(vehicle={"front": "−x", "top": "-z"})).vehicle == Vehicle("-x", "-z")


@pytest.mark.parametrize("vehicle, message", [
    ({"front": "forward", "top": "+z"}, "field body.vehicle.front must be one of +x, -x, +y, -y, +z, -z"),
    ({"front": "+y", "top": "up"}, "field body.vehicle.top must be one of +x, -x, +y, -y, +z, -z"),
    ({"front": "y", "top": "+z"}, "field body.vehicle.front must be one of +x, -x, +y, -y, +z, -z (the body axis "
                                  "that points to the vehicle's front), got 'y' (did you mean +y?)"),
    ({"front": "+z", "top": "-z"}, "field body.vehicle: front +z and top -z lie on the same body axis"),
    ({"front": "+x", "top": "+x"}, "field body.vehicle: front +x and top +x lie on the same body axis"),
    ({"front": "+x"}, "missing field body.vehicle.top"),
    ({"front": "+x", "top": "+z", "left": "+y"}, "unknown field body.vehicle.left"),
    ("+x", "field body.vehicle must be a mapping"),
])
def test_bad_vehicle_is_refused_at_load_naming_the_field(vehicle, message):
    with pytest.raises(RigError) as e:
        rig_from_dict(rig_dict(vehicle=vehicle), "my_rig.yaml")
    assert str(e.value).startswith("my_rig.yaml: ") and message in str(e.value), str(e.value)


@pytest.mark.parametrize("axes", ["sae", "iso8855"])
def test_vehicle_axes_as_output_axes_need_the_vehicle(axes):
    with pytest.raises(RigError) as e:
        rig_from_dict(rig_dict() | {"output_axes": axes}, "my_rig.yaml")
    assert str(e.value).startswith("my_rig.yaml: field output_axes") and "body.vehicle" in str(e.value), str(e.value)
    rig = rig_from_dict(rig_dict(vehicle={"front": "+y", "top": "+z"}) | {"output_axes": axes})
    assert rig.output_axes == axes and rig.to_dict()["output_axes"] == axes


# --- the vehicle axes: J' = R J Rᵀ ------------------------------------------------------------------

@pytest.mark.parametrize("name, R", [("sae", SAE_BY_HAND), ("iso8855", ISO_BY_HAND)])
def test_vehicle_tensor_is_the_body_tensor_turned(name, R):
    """Front +y, top +z: in the vehicle axes Ixx (roll) is the body's Iyy, Iyy (pitch) the body's
    Ixx, Izz (yaw) the body's Izz; each product is a body product with the sign R gives it; the
    CG turns with R, σ goes with its entry and the principal moments stay."""
    assert np.linalg.det(R) == pytest.approx(1.0)
    ex = express(1810.0, CG, J, STD, (), axes_for(name, FRONT_Y))
    np.testing.assert_allclose(ex.axes.rotation, R, atol=0)
    np.testing.assert_allclose(ex.tensor_cg, R @ J @ R.T, atol=1e-12)
    np.testing.assert_allclose(ex.cg, R @ CG, atol=1e-15)
    assert ex.entry("ixx") == J[1, 1] == 695.0          # roll moment: about the vehicle's front, body y
    assert ex.entry("iyy") == J[0, 0] == 2894.0         # pitch moment: body x
    assert ex.entry("izz") == J[2, 2] == 3101.0         # yaw moment: body z
    # the roll–yaw product (SAE Ixz, vehicle-dynamics sign) is the body's y–z product:
    # SAE: x' = y, z' = -z, so ∫x'z' dm = -∫yz dm; ISO: z' = z, so ∫x'z' dm = +∫yz dm
    body_Iyz = -J[1, 2]                                 # +102: the product ∫yz dm (the entry negated)
    assert ex.products()["Ixz"] == pytest.approx((-1.0 if name == "sae" else 1.0) * body_Iyz)
    # the pitch–yaw product ∫y'z' dm: SAE y' = x, z' = -z → -∫xz dm; ISO y' = -x, z' = z → -∫xz dm
    assert ex.products()["Iyz"] == pytest.approx(-(-J[0, 2]))
    # the roll–pitch product ∫x'y' dm: SAE y' = x → +∫xy dm; ISO y' = -x → -∫xy dm
    assert ex.products()["Ixy"] == pytest.approx((1.0 if name == "sae" else -1.0) * -J[0, 1])
    np.testing.assert_allclose(np.linalg.eigvalsh(ex.tensor_cg), np.linalg.eigvalsh(J), rtol=1e-12)
    np.testing.assert_allclose(ex.principal, np.linalg.eigvalsh(J), rtol=1e-12)
    # σ: each entry's is that of the body entry it is (ixx' = iyy, ixz' = ±iyz, iyz' = ±ixz)
    assert (ex.sigma("ixx"), ex.sigma("iyy"), ex.sigma("izz")) == (4.0, 1.0, 6.0)
    assert (ex.sigma("ixy"), ex.sigma("ixz"), ex.sigma("iyz")) == (2.0, 5.0, 3.0)
    # the covariance of the six entries turns as T C Tᵀ, T the entry map of R J Rᵀ
    T = ex.axes.entry_map
    rng = np.random.default_rng(3)
    for _ in range(3):
        theta = rng.normal(size=6)
        turned = R @ to_tensor(theta) @ R.T
        np.testing.assert_allclose(T @ theta, [turned[i, j] for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2),
                                                                         (2, 2))], atol=1e-12)
    # about the origin: the parallel-axis theorem in the turned axes is the turned body one
    body = express(1810.0, CG, J, STD)
    np.testing.assert_allclose(ex.tensor_origin, R @ body.tensor_origin @ R.T, atol=1e-9)
    # an undetermined body entry leaves the entry it becomes undetermined, and only that one
    partial = express(1810.0, CG, J, STD, ("iyz",), axes_for(name, FRONT_Y))
    assert partial.undetermined == {"ixz"} and partial.entry("ixz") is None and partial.principal is None
    assert partial.entry("ixx") == 695.0
    block = axes_block(ex)
    assert block["inertia_about_cg"]["ixx"] == 695.0 and name.upper()[:3] in block["axes"]


def test_front_x_top_z_keeps_the_half_turn():
    """Front +x, top +z: SAE J670 is the body frame turned half a turn about x (what --axes sae
    assumed before), ISO 8855 the body frame itself."""
    ex = express(1810.0, CG, J, STD, (), axes_for("sae", Vehicle("+x", "+z")))
    np.testing.assert_allclose(ex.axes.rotation, np.diag([1.0, -1.0, -1.0]), atol=0)
    assert ex.entry("ixy") == -J[0, 1] and ex.entry("iyz") == J[1, 2]
    np.testing.assert_allclose(axes_for("iso8855", Vehicle("+x", "+z")).rotation, np.eye(3), atol=0)


@pytest.mark.parametrize("front", ["+x", "-x", "+y", "-y", "+z", "-z"])
@pytest.mark.parametrize("top", ["+x", "-x", "+y", "-y", "+z", "-z"])
def test_every_orientation_gives_a_proper_rotation(front, top):
    if front[1] == top[1]:
        with pytest.raises(ValueError):
            Vehicle(front, top)
        return
    v = Vehicle(front, top)
    for name in ("sae", "iso8855"):
        R = axes_for(name, v).rotation
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=0)
        assert np.linalg.det(R) == pytest.approx(1.0)
        assert R[0] @ v.forward == 1.0                              # x forward in both
        assert R[2] @ v.up == (-1.0 if name == "sae" else 1.0)      # z down (SAE), up (ISO)


def test_without_the_vehicle_the_vehicle_axes_are_refused():
    for name in ("sae", "iso8855"):
        with pytest.raises(AxesError, match="body.vehicle"):
            axes_for(name)
        with pytest.raises(AxesError, match="body.vehicle"):
            express(1810.0, CG, J, STD, (), name)
    with pytest.raises(AxesError, match="known: body, sae, iso8855"):
        axes_for("vehicle", FRONT_Y)


# --- the words ------------------------------------------------------------------------------------

def test_words_in_the_text_follow_the_vehicle():
    """Front +y: in body axes Iyy is the roll moment, Ixx the pitch moment, Iyz the roll–yaw
    product; in SAE axes Ixx is the roll moment.  Without body.vehicle no row, no frame line and
    no principal axis says roll, pitch or yaw."""
    rows = {ln.split()[0]: ln for ln in tensor_table(express(1810.0, CG, J, STD, (), axes_for("body", FRONT_Y)))[1:]}
    assert rows["Iyy"].endswith("  roll moment") and rows["Ixx"].endswith("  pitch moment")
    assert rows["Izz"].endswith("  yaw moment") and rows["Iyz"].endswith("  roll–yaw product")
    assert rows["Ixy"].endswith("  roll–pitch product") and rows["Ixz"].endswith("  pitch–yaw product")
    sae = {ln.split()[0]: ln for ln in tensor_table(express(1810.0, CG, J, STD, (), axes_for("sae", FRONT_Y)))[1:]}
    assert sae["Ixx"].endswith("  roll moment") and float(sae["Ixx"].split()[1]) == 695.0
    assert sae["Ixz"].endswith("  roll–yaw product")
    front_y = express(1810.0, CG, J, STD, (), axes_for("body", FRONT_Y))
    assert any("from y (roll axis)" in ln for ln in principal_lines(front_y))
    assert "the vehicle's front along +y, its top along +z" in convention_lines(front_y.axes)[0]
    plain = express(1810.0, CG, J, STD)
    text = "\n".join(tensor_table(plain) + principal_lines(plain) + convention_lines(plain.axes))
    assert not WORDS.search(text), text
    assert "x forward" not in text


def test_report_words_follow_the_vehicle():
    """The report's tensor table and principal axes: "Iyy (roll moment)", "Ixx (pitch moment)"
    with front +y; "Ixx (moment about x)" and no roll, pitch or yaw without it."""
    mp = mass_properties_of(1810.0, CG, J, STD, np.diag(STD ** 2), None, (), FRONT_Y)
    table = moments_table(mp, None)
    assert "Iyy (roll moment)" in table and "Ixx (pitch moment)" in table and "Izz (yaw moment)" in table
    assert "Iyz (product, y–z (roll–yaw))" in table
    assert "body y (roll axis)" in principal_html(mp)
    assert "front along +y" in convention(mp.axes)
    plain = mass_properties_of(1810.0, CG, J, STD, np.diag(STD ** 2), None)
    html = moments_table(plain, None) + principal_html(plain) + convention(plain.axes)
    assert "Ixx (moment about x)" in html and "Iyy (moment about y)" in html
    assert not WORDS.search(html), WORDS.search(html)
    assert "x forward" not in html


# --- the command line --------------------------------------------------------------------------

@pytest.mark.parametrize("axes", ["sae", "iso8855"])
def test_cli_refuses_vehicle_axes_without_the_vehicle_before_reading(tmp_path, axes):
    """--axes sae / iso8855 on a rig.yaml without body.vehicle: exit status 2 at once (the folder
    has no bag: the refusal comes before the recording is read), naming rig.yaml's body.vehicle."""
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "rig.yaml").write_text(yaml.safe_dump(rig_dict()))
    code, out, err = run_cli("inertia", rec, "--axes", axes, "--quiet")
    assert code == 2 and out == "", (code, out, err)
    assert err.startswith(f"rig-identify: error: --axes {axes}: ") and "body.vehicle" in err, err
    assert "Traceback" not in err


def test_output_axes_follow_the_recordings_rig_yaml():
    """The axes of several recordings: their rig.yaml's output_axes and vehicle when they agree."""
    from types import SimpleNamespace

    def rec(axes=None, vehicle=None):
        return SimpleNamespace(rig=SimpleNamespace(output_axes=axes, vehicle=vehicle))
    ax, notes = output_axes(None, [rec("sae", FRONT_Y), rec("sae", FRONT_Y)])
    assert ax.name == "sae" and ax.rotation[0] @ FRONT_Y.forward == 1.0 and notes == []
    ax, notes = output_axes(None, [rec()])
    assert ax.name == "body" and ax.vehicle is None and notes == []
    ax, notes = output_axes("iso8855", [rec(vehicle=FRONT_Y), rec()])   # one states it, the other not
    assert ax.name == "iso8855" and notes == []
    ax, notes = output_axes(None, [rec("sae", FRONT_Y), rec("body", FRONT_Y)])
    assert ax.name == "body" and "different output_axes" in notes[0]
    # two rig.yaml that disagree on the vehicle: unknown, said; vehicle axes then refused
    assert common_vehicle([FRONT_Y, Vehicle("-y", "+z")])[0] is None
    ax, notes = output_axes(None, [rec(vehicle=FRONT_Y), rec(vehicle=Vehicle("-y", "+z"))])
    assert ax.vehicle is None and "different body.vehicle" in notes[0]
    with pytest.raises(AxesError, match="different body.vehicle"):
        output_axes("sae", [rec(vehicle=FRONT_Y), rec(vehicle=Vehicle("-y", "+z"))])

