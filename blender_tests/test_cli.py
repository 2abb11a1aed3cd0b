"""The headless entry point penumbra/cli.py, run as users run it: a separate `blender -b file.blend`."""
import json
import os
import subprocess

import bpy

import cornell_box

ADDON_DIR = os.environ.get("PENUMBRA_ADDON_DIR", "")


def _run(blend, *args):
    cli = os.path.join(ADDON_DIR, "penumbra", "cli.py")
    cmd = ["blender", "-b", blend, "--factory-startup", "--python-exit-code", "1", "--python", cli, "--", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=180)


def test_cli_bakes_and_reports(empty_scene, tmp_path):
    cornell_box.build()
    blend = str(tmp_path / "box.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    out = tmp_path / "out"
    r = _run(blend, "--out", str(out), "--resolution", "32", "--epsilon", "0.004")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "penumbra: solve" in r.stderr
    assert "Penumbra: 8 objects baked" in r.stdout
    report = json.loads((out / "report.json").read_text())
    assert report["objects_baked"] and report["links"] > 0
    assert (out / "Penumbra_Floor.exr").is_file() and (out / "baked.blend").is_file()


def test_cli_fails_clearly(empty_scene, tmp_path):
    cornell_box.build()
    blend = str(tmp_path / "box.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    r = _run(blend, "--out", str(tmp_path / "o"), "--uv-map", "Missing")
    assert r.returncode != 0
    assert "UV map 'Missing' is missing on" in r.stderr
    r = _run(blend, "--help")
    assert r.returncode == 0 and "--resolution" in r.stdout
    r = _run(blend, "--no-such-option")
    assert r.returncode != 0
