"""A user's config folder is searched before the package's conf/: a file of a shipped name
(study/quick.yaml, ppo/smoke.yaml) replaces the shipped one for Hydra's groups, as it already
does for sigmarl's own scenario and map lookups; without the folder the shipped file is back."""

from __future__ import annotations

import os

from sigmarl.compose import compose_config
from sigmarl.paths import CONFIG_PATH, add_user_conf_dir

MINE = """\
# @package _global_
study:
  name: my_quick
  variants:
    M0: [obs=full]
  baseline: M0
  seeds: [7]
  scenarios: [Intersection]
"""


def test_a_users_file_of_a_shipped_name_shadows_it(tmp_path, monkeypatch):
    monkeypatch.setenv(CONFIG_PATH, "")  # recorded, so that teardown removes what add_user_conf_dir sets
    shipped = compose_config(["study=quick"])
    (tmp_path / "study").mkdir()
    (tmp_path / "study" / "quick.yaml").write_text(MINE)
    (tmp_path / "ppo").mkdir()
    (tmp_path / "ppo" / "smoke.yaml").write_text("# @package ppo\niterations: 2\n")
    add_user_conf_dir(tmp_path)
    mine = compose_config(["study=quick", "ppo=smoke"])
    assert (mine.study.name, list(mine.study.seeds)) == ("my_quick", [7])
    assert shipped.study.name == "quick"
    assert mine.ppo.iterations == 2  # the rest of ppo comes from the schema's defaults
    os.environ[CONFIG_PATH] = ""
    assert compose_config(["study=quick"]).study.name == "quick"
