"""Scenario fields contacts, walls and obstacles: YAML and one-line forms, the ROS string
parameter, and bad values that exit naming the field and what is allowed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rclpy.parameter import Parameter

from aes_ros import scenario
from aes_ros.cli import main
from aes_ros.obstacles import contact_arrays, format_obstacles
from aes_ros.params import PARAMS, ParameterError
from aes_ros.ros.parameters import check, to_ros_value

LINE = "circle:1,0.5,0.1;box:2,2.2,-1,1"
PARSED = (("circle", (1.0, 0.5, 0.1)), ("box", (2.0, 2.2, -1.0, 1.0)))


def test_no_walls_and_no_obstacles_by_default() -> None:
    sc = scenario.load("combined")
    assert sc.contacts is PARAMS["contacts"].default
    walls, circles, boxes = contact_arrays(sc.values)
    assert walls.shape == (0,) and circles.shape == (0, 3) and boxes.shape == (0, 4)


def test_yaml_and_one_line_forms_agree(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(
        "contacts: true\nwalls: [-3, 3, -2, 2]\n"
        "obstacles: [{circle: [1.0, 0.5, 0.1]}, {box: [2, 2.2, -1, 1]}]\n"
    )
    from_yaml = scenario.load(path)
    from_line = scenario.load("combined", {"obstacles": LINE, "walls": "-3,3,-2,2"})
    assert from_yaml.obstacles == from_line.obstacles == PARSED
    assert from_yaml.contacts is True
    walls, circles, boxes = contact_arrays(from_yaml.values)
    np.testing.assert_array_equal(walls, [-3, 3, -2, 2])
    np.testing.assert_array_equal(circles, [[1.0, 0.5, 0.1]])
    np.testing.assert_array_equal(boxes, [[2.0, 2.2, -1.0, 1.0]])
    assert scenario.load("combined", {"obstacles": ""}).obstacles == ()


def test_written_scenario_reads_back(tmp_path: Path) -> None:
    from aes_ros.ros.launch.param_files import write_scenario

    sc = scenario.load("combined", {"obstacles": LINE, "walls": "-3,3,-2,2", "contacts": "1"})
    back = scenario.load(write_scenario(sc, tmp_path / "scenario.yaml"))
    assert back.values == sc.values


def test_ros_parameter_is_the_one_line_string() -> None:
    spec = PARAMS["obstacles"]
    text = to_ros_value(spec, PARSED)
    assert text == LINE
    assert spec.validate(text) == PARSED
    assert check([Parameter("obstacles", Parameter.Type.STRING, text)]) is None
    reason = check([Parameter("obstacles", Parameter.Type.STRING, "circle:0,0,-1")])
    assert reason is not None and reason.startswith("obstacles:") and "r > 0" in reason
    assert format_obstacles(()) == ""


@pytest.mark.parametrize(
    ("value", "why"),
    [
        ("circle:1,2", "needs 3 numbers"),
        ("triangle:1,2,3", "unknown obstacle"),
        ("circle:1,2,0", "r > 0"),
        ("box:2,1,0,1", "x_min < x_max"),
        ("circle:1,nan,1", "finite"),
        ("circle:1,2e9,1", "finite"),
        ("circle", "kind:numbers"),
        ([{"circle": [0, 0, 1], "box": [0, 1, 0, 1]}], "one {circle"),
    ],
)
def test_bad_obstacles_are_refused_with_the_reason(value: object, why: str) -> None:
    with pytest.raises(ParameterError) as err:
        scenario.load("combined", {"obstacles": value})
    assert str(err.value).startswith("--set: obstacles:")
    assert why in str(err.value) and "circle:x,y,r" in str(err.value)


@pytest.mark.parametrize(
    ("assignment", "allowed"),
    [
        ("obstacles=circle:0,0,-0.1", "r > 0"),
        ("obstacles=box:0,1", "x_min,x_max,y_min,y_max"),
        ("walls=1,0,0,1", "x_min < x_max"),
        ("contacts=maybe", "true or false"),
    ],
)
def test_cli_exits_2_naming_the_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], assignment: str, allowed: str
) -> None:
    code = main(["simulate", "--set", assignment, "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"{assignment.partition('=')[0]}:" in err and allowed in err, err
    assert not (tmp_path / "x").exists()
