"""`resume` gives the resumed run a key of its own: the old run's per-run key file,
named in the bag's config, is used only to verify the old records, never to sign the new run."""
from __future__ import annotations

from bev_mdo.protocol.signing import with_run_key
from bev_mdo.cli.resume import is_per_run_key


def test_a_per_run_key_of_a_default_named_bag_is_recognised(tmp_path):
    # optimize's default bag name ends with the first 6 hex digits of the run id, not the whole id
    bag = tmp_path / "bags" / "leaf_nedc_20261201_201500_a1b2c3"
    config = with_run_key({"ros": {}}, bag.parent / ".keys" / bag.name)
    key = config["ros"]["sign_key_file"]
    assert is_per_run_key(key)
    named = with_run_key({"ros": {}}, tmp_path / "out" / ".keys" / "trusted")  # --bag out/trusted
    assert is_per_run_key(named["ros"]["sign_key_file"])


def test_a_key_file_the_user_configured_is_kept(tmp_path):
    mine = tmp_path / "keys" / "team.key"
    mine.parent.mkdir()
    mine.write_text("0123456789abcdef0123456789abcdef")
    mine.chmod(0o600)
    assert not is_per_run_key(str(mine))
    assert not is_per_run_key("")
    assert with_run_key({"ros": {"sign_key_file": str(mine)}}, tmp_path / "x")["ros"]["sign_key_file"] == str(mine)


def test_resume_does_not_sign_the_new_run_with_the_old_runs_key(tmp_path, monkeypatch):
    import bev_mdo.cli.optimize as optimize
    import bev_mdo.cli.resume as resume
    from bev_mdo.cli import main
    from bev_mdo.config import load_config

    old_bag = tmp_path / "bags" / "leaf_nedc_20261201_201500_a1b2c3"
    config = with_run_key(load_config("config/leaf_nedc.yaml"), old_bag.parent / ".keys" / old_bag.name)
    old_key = config["ros"]["sign_key_file"]
    monkeypatch.setattr(resume, "resume_point", lambda *a, **k: (config, {"motor_kw": 80.0}, 3))
    seen = {}
    monkeypatch.setattr(optimize, "run_job", lambda cfg, opts, x0=None: seen.update(cfg=cfg, x0=x0) or 0)
    assert main(["resume", str(old_bag), "--no-record", "--quiet"]) == 0
    assert seen["x0"] == {"motor_kw": 80.0}
    assert seen["cfg"]["ros"].get("sign_key_file", "") != old_key  # a fresh key is made for the new run


def test_a_stored_config_that_no_longer_loads_is_named_as_the_bags(tmp_path, capsys):
    """The user module of a run's discipline moved away: resume's error named '<config>', not the bag."""
    import shutil
    import sys
    from pathlib import Path

    from bev_mdo.cli import main

    sellar = Path(__file__).resolve().parents[2] / "examples" / "sellar"
    shutil.copy(sellar / "sellar_disciplines.py", tmp_path / "moved_away_sellar.py")  # a module no other test imports
    config = (sellar / "sellar_mdf.yaml").read_text().replace("sellar_disciplines:", "moved_away_sellar:")
    (tmp_path / "sellar_mdf.yaml").write_text(config)
    bag = tmp_path / "bag"
    assert main(["optimize", str(tmp_path / "sellar_mdf.yaml"), "--transport", "inprocess", "--bag", str(bag),
                 "--quiet"]) == 0
    (tmp_path / "moved_away_sellar.py").unlink()
    sys.modules.pop("moved_away_sellar", None)  # as a new process finds it: not imported yet
    capsys.readouterr()
    assert main(["resume", str(bag), "--transport", "inprocess", "--output", str(tmp_path / "new"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{bag} (its stored config): disciplines" in err and "<config>" not in err, err
