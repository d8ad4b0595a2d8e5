"""CMU's ASF/AMC reader (mlct.motion.asf_amc): a made skeleton whose world positions are known
in closed form, and one-line errors for broken files."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.errors import MlctError
from mlct.motion.asf_amc import euler, read_amc, read_asf

ASF = """# a made skeleton: a leg of two bones down from the root, an arm out along +x
:version 1.10
:units
  length 0.45
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name femur
     direction 0 -1 0
     length 4
     axis 0 0 0 XYZ
    dof rx
  end
  begin
     id 2
     name tibia
     direction 0 -1 0
     length 3
     axis 0 0 0 XYZ
    dof rx
  end
  begin
     id 3
     name arm
     direction 1 0 0
     length 2
     axis 0 0 90 XYZ
    dof rx
  end
:hierarchy
  begin
    root femur arm
    femur tibia
  end
"""


def amc(frames):
    lines = [":FULLY-SPECIFIED", ":DEGREES"]
    for i, (root, femur, tibia, arm) in enumerate(frames, start=1):
        lines += [str(i), "root " + " ".join(map(str, root)), f"femur {femur}",
                  f"tibia {tibia}", f"arm {arm}"]
    return "\n".join(lines) + "\n"


def test_positions_follow_the_formats_kinematics(tmp_path):
    (tmp_path / "07.asf").write_text(ASF)
    (tmp_path / "07_01.amc").write_text(amc([
        ((0, 10, 0, 0, 0, 0), 0, 0, 0),       # rest
        ((1, 10, 0, 0, 0, 0), 90, 0, 0),      # the femur turned 90 degrees about x
        ((0, 10, 0, 0, 90, 0), 0, -90, 0),    # the root turned about y; the knee bent back
        ((0, 10, 0, 0, 0, 0), 0, 0, 90),      # the arm's rx about its axis frame (z by 90)
    ]))
    clip = read_amc(tmp_path / "07_01.amc")
    names = clip.joint_names
    assert names == ("root", "femur", "arm", "tibia") and clip.fps == 120.0
    at = {n: clip.positions[:, names.index(n)] for n in names}
    # a joint sits where its bone starts: the femur's at the root, the tibia's at the knee
    np.testing.assert_allclose(at["femur"][0], [0, 10, 0])
    np.testing.assert_allclose(at["tibia"][0], [0, 6, 0])
    np.testing.assert_allclose(at["tibia"][1], [1, 10, -4], atol=1e-12)  # Rx(90): -y to -z
    # the root turned about y leaves a bone along -y where it was; a bone's own rotation
    # never moves its start
    np.testing.assert_allclose(at["tibia"][2], [0, 6, 0], atol=1e-12)
    # the arm's rotation about x is about its axis frame's x, which the axis line turned to +y
    np.testing.assert_allclose(at["arm"][3], [0, 10, 0], atol=1e-12)


def test_the_arms_axis_frame_turns_its_rotation(tmp_path):
    """An end point checked through a child: C M C^-1 with C = Rz(90) turns rx into a turn
    about world y, so the arm (along +x) swings to -z."""
    asf = ASF.replace("""  begin
     id 3""", """  begin
     id 4
     name hand
     direction 1 0 0
     length 1
     axis 0 0 0 XYZ
  end
  begin
     id 3""").replace("    root femur arm", "    root femur arm\n    arm hand")
    (tmp_path / "08.asf").write_text(asf)
    (tmp_path / "08_01.amc").write_text(amc([((0, 10, 0, 0, 0, 0), 0, 0, 90)]).replace(
        "arm 90", "arm 90\nhand"))
    clip = read_amc(tmp_path / "08_01.amc")
    hand = clip.positions[0, clip.joint_names.index("hand")]
    np.testing.assert_allclose(hand, [0, 10, -2], atol=1e-12)


def test_euler_applies_its_first_letter_first():
    x = euler(np.array([90.0, 0.0, 0.0]), "XYZ")
    np.testing.assert_allclose(x @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    xz = euler(np.array([90.0, 0.0, 90.0]), "XYZ")  # x first, then z
    np.testing.assert_allclose(xz @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(xz @ [1, 0, 0], [0, 1, 0], atol=1e-12)


@pytest.mark.parametrize("asf, take, message", [
    (":version 1.10\n", "1\nroot 0 0 0 0 0 0\n", "not an ASF skeleton"),
    (ASF, ":DEGREES\n", "no frames"),
    (ASF, "1\nroot 0 0 0 0 0 0\nfemur x\n", "frame 1: not numbers"),
    (ASF, "1\nroot 0 0 0 0 0 0\nfemur 0\n", "a frame has no values for"),
])
def test_broken_files_are_one_line_errors(tmp_path, asf, take, message):
    (tmp_path / "09.asf").write_text(asf)
    (tmp_path / "09_01.amc").write_text(take)
    with pytest.raises(MlctError, match=message):
        read_amc(tmp_path / "09_01.amc")
    with pytest.raises(MlctError, match="cannot read"):
        read_asf(tmp_path / "missing.asf")
