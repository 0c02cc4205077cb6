"""`sigmarl maps list|show` end to end: real configs, real PNG files."""

from __future__ import annotations

from pathlib import Path

import pytest

from sigmarl.cli import main

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
DATA = Path(__file__).parent / "data"


def assert_png(path: Path) -> None:
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 10_000  # a drawn map, not an empty canvas


@pytest.mark.parametrize(
    "name", ["cpm", "paper_intersection", "paper_on_ramp", "paper_roundabout", "intersection", "on_ramp", "roundabout",
             "interchange_1", "interchange_2", "interchange_3", "intersection_1", "intersection_3", "intersection_4",
             "intersection_5", "intersection_6", "intersection_7", "intersection_8", "on_ramp_2_multilane",
             "roundabout_2"]
)
def test_show_writes_png(tmp_path, capsys, name):
    out = tmp_path / f"{name}.png"
    assert main(["maps", "show", name, "--out", str(out)]) == 0
    assert_png(out)
    assert str(out) in capsys.readouterr().out


def test_show_osm_file_with_ids(tmp_path):
    out = tmp_path / "l2.png"
    assert main(["maps", "show", str(DATA / "lanelet2_two_way.osm"), "--out", str(out), "--ids"]) == 0
    assert_png(out)


def test_show_unknown_map_fails(capsys):
    assert main(["maps", "show", "nope"]) != 0
    err = capsys.readouterr().err
    assert "unknown map 'nope'" in err and "Traceback" not in err


def test_show_broken_osm_fails_with_file_name(tmp_path, capsys):
    bad = tmp_path / "broken.osm"
    bad.write_text("<osm><node id='1'")
    assert main(["maps", "show", str(bad), "--out", str(tmp_path / "x.png")]) != 0
    assert "broken.osm: not well-formed XML" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_list_prints_every_map(capsys):
    assert main(["maps", "list"]) == 0
    rows = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines()[1:]}
    assert set(rows) == {"cpm", "cpm_intersection", "intersection", "on_ramp", "roundabout",
                         "paper_intersection", "paper_on_ramp", "paper_roundabout", "interchange_1",
                         "interchange_2", "interchange_3", "intersection_1", "intersection_3",
                         "intersection_4", "intersection_5", "intersection_6", "intersection_7",
                         "intersection_8", "on_ramp_2_multilane", "roundabout_2"}
    # lanelets and routes columns
    assert rows["cpm"][1:3] == ["104", "7"]
    assert rows["cpm_intersection"][2] == "24"
    assert [rows[f"paper_{k}"][1:3] for k in ("intersection", "on_ramp", "roundabout")] == [
        ["11", "6"], ["7", "4"], ["9", "5"]]
    assert rows["intersection"][1:3] == ["20", "12"]
    # SigmaRL's later maps: lanelets, routes and lane width (the facts' counts)
    assert rows["interchange_2"][1:3] + rows["interchange_2"][-1:] == ["16", "16", "0.20"]
    assert rows["intersection_4"][1:3] + rows["intersection_4"][-1:] == ["20", "12", "0.30"]
    assert rows["on_ramp_2_multilane"][1:3] == ["26", "21"]
    assert rows["on_ramp"][1:3] == ["5", "3"]
    assert rows["roundabout"][1:3] == ["24", "16"]


def test_missing_packaged_map_exits_2(capsys):
    rc = main(["maps", "show", "paper_roundabout", "map.path=package:maps/nope.osm"])
    assert rc == 2
    assert "map.path=package:maps/nope.osm: no such file in the sigmarl package" in capsys.readouterr().err



@pytest.mark.parametrize("name", sorted(p.stem for p in (Path(__file__).parents[1] / "conf" / "map").glob("*.yaml")
                                        if p.stem != "osm"))
def test_list_reads_each_map_file_as_composition_would(name):
    """`maps list` reads each conf/map file on its own (no Hydra composition per map): the same
    map config that `map=<name>` composes."""
    from sigmarl.compose import compose_config
    from sigmarl.maps import map_config

    assert map_config(name) == compose_config([f"map={name}"]).map


def test_list_into_a_closed_pipe_is_quiet(tmp_path):
    import subprocess
    import sys

    done = subprocess.run(f"{sys.executable} -m sigmarl maps list | head -n 1", shell=True, cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.stdout.split() == ["map", "lanelets", "routes", "size", "(m)", "lane", "width"]
    assert done.stderr == ""


def test_a_map_name_in_any_case_and_a_misspelt_one_gets_did_you_mean(tmp_path, monkeypatch, capsys):
    from cli_errors import one_line_exit_2

    from sigmarl.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["maps", "show", "Paper_Roundabout"]) == 0
    # drawn as paper_roundabout, into the reports folder: nothing loose in the working folder
    assert [p.relative_to(tmp_path) for p in tmp_path.rglob("*.png")] == [Path("reports/maps/paper_roundabout.png")]
    line = one_line_exit_2(["maps", "show", "roundabot"], capsys)
    assert "unknown map 'roundabot' (did you mean roundabout?)" in line


def test_a_misspelt_scenario_gets_did_you_mean(capsys):
    from cli_errors import one_line_exit_2

    line = one_line_exit_2(["train", "ppo=smoke", "eval.scenarios=[Roundabot]", "tracking.enabled=false"], capsys)
    assert "unknown scenario 'Roundabot' (did you mean Roundabout?)" in line
