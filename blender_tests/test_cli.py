"""The headless entry point penumbra/cli.py, run as users run it: a separate `blender -b file.blend`."""
import json
import os
import subprocess

import bpy

import cornell_box

ADDON_DIR = os.environ.get("PENUMBRA_ADDON_DIR", "")


def _own_traceback(stderr):
    """A Python traceback in the CLI's stderr other than sid's Blender printing one at every start from its
    bundled bl_pkg add-on (python3-cattrs is not packaged there)."""
    blocks = stderr.split("Traceback (most recent call last):")[1:]
    return any("bl_pkg" not in b for b in blocks)


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


def _box_file(tmp_path, **panel):
    bpy.ops.wm.read_homefile(use_empty=True)
    cornell_box.build()
    for k, v in panel.items():
        setattr(bpy.context.scene.penumbra, k, v)
    blend = str(tmp_path / "box.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    return blend


def test_cli_uses_the_panel_settings_and_the_options_override_them(empty_scene, tmp_path):
    blend = _box_file(tmp_path, resolution=24, color_attribute=False)
    out = tmp_path / "a"
    r = _run(blend, "--out", str(out), "--quality", "draft", "--save", "none")
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads((out / "report.json").read_text())
    assert report["settings"]["resolution"] == 24                # from the file's panel
    assert report["settings"]["targets"] == ["LIGHTMAP"]
    assert report["settings"]["epsilon"] == 0.002 and report["settings"]["min_size"] == 0.02   # --quality
    assert not (out / "baked.blend").exists()
    out = tmp_path / "b"
    r = _run(blend, "--out", str(out), "--quality", "draft", "--resolution", "16", "--targets", "color",
             "--epsilon", "0.004", "--visibility-rays", "4", "--refine-passes", "1", "--patch-texels", "1.5")
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads((out / "report.json").read_text())
    s = report["settings"]
    assert (s["resolution"], s["targets"], s["epsilon"], s["visibility_rays"]) == (16, ["COLOR_ATTRIBUTE"], 0.004, 4)
    assert s["patch_texels"] == 1.5
    assert report["refine_passes"] == 1
    assert not list(out.glob("*.exr"))                           # color attributes only


def test_cli_exit_codes(empty_scene, tmp_path):
    blend = _box_file(tmp_path)
    r = _run(blend, "--help")
    assert r.returncode == 0
    for flag in ("--quality", "--targets", "--min-size", "--visibility-rays", "--refine-passes", "Exit codes"):
        assert flag in r.stdout
    r = _run(blend, "--out", str(tmp_path / "o"), "--resolution", "3")
    assert r.returncode == 2 and "must be between 8 and 8192" in r.stderr
    r = _run(blend, "--out", str(tmp_path / "o"), "--resolution", "8193")
    assert r.returncode == 2 and "must be between 8 and 8192, got 8193" in r.stderr
    # Solver settings stop where the solver does (settings_table.py): 257 rays is a bad option, not a failed bake.
    r = _run(blend, "--out", str(tmp_path / "o"), "--visibility-rays", "257")
    assert r.returncode == 2 and "must be in [1, 256], got 257" in r.stderr
    r = _run(blend, "--out", str(tmp_path / "o"), "--targets", "texture")
    assert r.returncode == 2 and "lightmap, color or both" in r.stderr
    # A scene that cannot be baked: no light. The message says what to add; report.json holds it too.
    bpy.data.objects.remove(bpy.data.objects["Lamp"])
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    out = tmp_path / "dark"
    r = _run(blend, "--out", str(out), "--quality", "draft")
    assert r.returncode == 3, r.stderr[-2000:]
    assert "penumbra: error: nothing emits light" in r.stderr
    assert json.loads((out / "report.json").read_text())["exit_code"] == 3
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    r = _run(blend, "--out", str(tmp_path / "empty"))
    assert r.returncode == 3 and "nothing to bake" in r.stderr
    r = _run(blend, "--out", str(tmp_path / "empty"), "--scene", "Nope")
    assert r.returncode == 2 and "no scene named 'Nope'" in r.stderr


def test_cli_out_naming_a_file_and_unwritable_save_exit_with_the_documented_codes(empty_scene, tmp_path):
    cornell_box.build()
    blend = str(tmp_path / "box.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    a_file = tmp_path / "not_a_folder"
    a_file.write_text("x")
    r = _run(blend, "--out", str(a_file), "--resolution", "16")
    assert r.returncode == 2, r.stderr[-2000:]
    assert "is a file" in r.stderr and not _own_traceback(r.stderr)
    assert a_file.read_text() == "x"
    for save in (str(tmp_path / "missing" / "x.blend"), str(tmp_path)):
        out = tmp_path / "o"
        r = _run(blend, "--out", str(out), "--resolution", "16", "--save", save)
        assert r.returncode == 2, r.stderr[-2000:]
        assert not _own_traceback(r.stderr) and "--save" in r.stderr
        report = json.loads((out / "report.json").read_text())
        assert report["exit_code"] == 2 and "--save" in report["error"]
        # Refused before the bake: no lightmap was written for a run that failed.
        assert sorted(p.name for p in out.iterdir()) == ["report.json"]
