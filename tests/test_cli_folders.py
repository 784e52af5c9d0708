"""Output folders hold one command's results, complete, or the earlier ones untouched (issue 28).

Every solving call is the ideal slider-crank over a quarter revolution (one small compilation,
shared by the tests of this file); the refusals happen before anything is solved.
"""

import json
from pathlib import Path

import pytest

import jaxclear.cli._run
from jaxclear import cli

RUN = [
    "run",
    "--clearance-joints",
    "none",
    "--revolutions",
    "0.25",
    "--skip-revolutions",
    "0",
    "--points-per-revolution",
    "90",
    "--no-progress",
    "--quiet",
]
MC_CONFIG = Path(__file__).parents[1] / "examples" / "montecarlo_h7g6.toml"


def run(out, *extra):
    return cli.main([*RUN, "--out", str(out), *extra])


def refused(capsys, argv, match):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith("jaxclear: error: "), err
    assert match in err, err
    return err


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def leftovers(parent: Path) -> list[str]:
    return sorted(p.name for p in parent.iterdir() if ".partial-" in p.name or ".old-" in p.name)


def test_same_configuration_is_replaced_whole(tmp_path):
    out = tmp_path / "o"
    assert run(out) == 0
    first = json.loads((out / "run.json").read_text())
    (out / "stray.txt").write_text("left by hand")
    assert run(out) == 0
    assert not (out / "stray.txt").exists(), "the folder holds one run: the new one, whole"
    assert json.loads((out / "run.json").read_text())["config"] == first["config"]
    assert leftovers(tmp_path) == []
    # whether compiled programs are cached changes no result: not another configuration
    assert run(out, "--no-compilation-cache") == 0


def test_another_configuration_is_refused_then_forced(tmp_path, capsys):
    out = tmp_path / "o"
    assert run(out) == 0
    before = snapshot(out)
    refused(capsys, [*RUN, "--rpm", "3000", "--out", str(out)], "(changed: mechanism.rpm)")
    assert snapshot(out) == before
    assert run(out, "--rpm", "3000", "--force") == 0
    assert json.loads((out / "run.json").read_text())["config"]["mechanism"]["rpm"] == 3000
    aside = [p for p in tmp_path.iterdir() if p.name.startswith("o.replaced-")]
    assert len(aside) == 1 and snapshot(aside[0]) == before, "--force moves aside, deletes nothing"


def test_another_commands_folder_is_refused(tmp_path, capsys):
    out = tmp_path / "mc"
    out.mkdir()
    (out / "samples.csv").write_text("index,B.clearance\n0,3e-4\n")  # a manifest-less ensemble
    refused(capsys, [*RUN, "--out", str(out)], "no jaxclear manifest accounts for")
    (out / "ensemble.json").write_text(json.dumps({"table": "samples.csv"}))
    refused(capsys, [*RUN, "--out", str(out)], "the results of 'jaxclear montecarlo'")
    assert sorted(p.name for p in out.iterdir()) == ["ensemble.json", "samples.csv"]


def test_montecarlo_refuses_a_folder_whose_manifest_is_gone(tmp_path, capsys):
    """Issue 28, item 1: 24 finished members, ensemble.json deleted, another configuration run
    into the folder: it replaced samples.csv (exit 0). Now refused before anything is solved."""
    out = tmp_path / "mc"
    out.mkdir()
    rows = "".join(f"{i},{3e-4 + 1e-6 * i!r},ok\n" for i in range(24))
    (out / "samples.csv").write_text("index,B.clearance,status\n" + rows)
    (out / "summary.json").write_text("{}")
    before = snapshot(out)
    argv = ["montecarlo", str(MC_CONFIG), "--samples", "8", "--quiet", "--out", str(out)]
    refused(capsys, argv, "no jaxclear manifest accounts for")
    assert snapshot(out) == before


def test_a_failed_write_leaves_the_earlier_run_untouched(tmp_path, monkeypatch):
    """Issue 28, item 2: a write that fails half-way left new files beside old ones. The results
    are staged beside --out and moved into place only when complete."""
    out = tmp_path / "o"
    assert run(out) == 0
    before = snapshot(out)

    def broken(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(jaxclear.cli._run, "write_results", broken)
    with pytest.raises(SystemExit) as exc:
        run(out)
    assert exc.value.code == 1
    assert snapshot(out) == before
    assert leftovers(tmp_path) == []


def test_an_unwritable_file_in_the_earlier_run_does_not_mix_runs(tmp_path):
    out = tmp_path / "o"
    assert run(out, "--no-plots") == 0
    (out / "results.csv").unlink()
    (out / "results.csv").mkdir()  # a name the new results.csv cannot replace in place
    assert run(out, "--no-plots") == 0
    assert (out / "results.csv").is_file()
    assert leftovers(tmp_path) == []


def test_a_changed_per_joint_table_is_another_configuration(tmp_path, capsys):
    """The check compared the settings only, so a changed [clearance.<joint>] table (its film, or
    any per-joint key) replaced a folder of another mechanism without a word. The file's tables
    count now. (--clearance-joints none keeps the one shared ideal solve; the per-joint tables are
    still read and checked, and compared as the file gives them.)"""
    out = tmp_path / "o"
    config = tmp_path / "lubricated.toml"
    table = "[clearance.B]\nclearance = 2e-4\nlubrication = {{ viscosity = 0.4, length = {} }}\n"
    config.write_text(table.format(0.01))
    argv = [*RUN, "--no-plots", str(config), "--out", str(out)]
    assert cli.main(argv) == 0
    assert cli.main(argv) == 0, "the same file is the same configuration"
    before = snapshot(out)
    recorded = json.loads(before["run.json"])["clearance_per_joint"]["B"]
    assert recorded == {"clearance": 2e-4, "lubrication": {"viscosity": 0.4, "length": 0.01}}
    config.write_text(table.format(0.04))
    refused(capsys, argv, "(changed: clearance.B.lubrication.length)")
    config.write_text(table.format(0.01).replace("2e-4", "3e-4"))
    refused(capsys, argv, "(changed: clearance.B.clearance)")
    config.write_text(table.format(0.01) + "[clearance.A]\nclearance = 1e-4\n")
    refused(capsys, argv, "(changed: clearance.A)")
    assert snapshot(out) == before
