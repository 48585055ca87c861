"""The Python package against the command: the same files byte for byte,
the same messages, windows that assemble into the single run's file, a
Dask cluster making them, Ctrl-C leaving nothing behind.

The command compared against is GCM_ORTHO_BIN (the cargo-built binary)
where set, else the `gcm-ortho` this package installs."""

import filecmp
import json
import os
import signal
import subprocess
import sysconfig
import threading
import warnings

import numpy as np
import pytest

import gcm_ortho

# The command this package installs, beside its interpreter.
INSTALLED = os.path.join(sysconfig.get_path("scripts"), "gcm-ortho")
BIN = os.environ.get("GCM_ORTHO_BIN") or INSTALLED


def command(*args, cwd=None):
    return subprocess.run([BIN, *map(str, args)], capture_output=True, text=True, cwd=cwd)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("scene")
    out = command("synth", "--out", d, "--size", "1500x1200", "--seed", "3", "--quiet")
    assert out.returncode == 0, out.stderr
    return d


@pytest.fixture(scope="module")
def single(scene):
    """The command's orthophoto of the scene at the defaults."""
    out = scene / "cli.tif"
    r = command("rectify", "--image", scene / "scan.tif", "--camera", scene / "camera.toml", "--dem", scene / "dem.tif", "-o", out, "--quiet")
    assert r.returncode == 0, r.stderr
    return out


def test_rectify_writes_the_commands_file_byte_for_byte(scene, single, tmp_path):
    out = tmp_path / "py.tif"
    report = gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif", out, json=tmp_path / "r.json")
    assert filecmp.cmp(single, out, shallow=False)
    with open(tmp_path / "r.json") as f:
        assert json.load(f) == report
    assert report["grid"]["width"] == 1460 and report["grid"]["height"] == 1222
    assert report["error_within"] is True
    assert report["output_bytes"] == os.path.getsize(out)


def test_settings_by_key_match_the_flags(scene, tmp_path):
    cli = tmp_path / "cli.tif"
    r = command(
        "rectify", "--image", scene / "scan.tif", "--camera", scene / "camera.toml", "--dem", scene / "dem.tif",
        "-o", cli, "--gsd", "2.5", "--compress", "zstd", "--resample", "cubic", "--nodata", "0", "--quiet",
    )
    assert r.returncode == 0, r.stderr
    py = tmp_path / "py.tif"
    report = gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif", py, gsd=2.5, compress="zstd", resample="cubic", nodata=0)
    assert filecmp.cmp(cli, py, shallow=False)
    assert report["config"]["compress"] == "Zstd" or report["config"]["compress"].lower() == "zstd"


def test_numpy_values_are_taken_and_other_objects_refused_by_key(scene, tmp_path):
    cli = tmp_path / "cli.tif"
    r = command("rectify", "--image", scene / "scan.tif", "--camera", scene / "camera.toml", "--height", "350", "--gsd", "2.5,3", "-o", cli, "--quiet")
    assert r.returncode == 0, r.stderr
    py = tmp_path / "py.tif"
    gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", np.float32(350), py, gsd=np.array([2.5, 3.0]))
    assert filecmp.cmp(cli, py, shallow=False)
    with pytest.raises(gcm_ortho.SettingError, match=r"^gsd: .* is not a value a setting takes"):
        gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", 350, tmp_path / "x.tif", gsd=object())
    assert not (tmp_path / "x.tif").exists()


def test_a_constant_height_is_a_number(scene, tmp_path):
    cli = tmp_path / "cli.tif"
    r = command("rectify", "--image", scene / "scan.tif", "--camera", scene / "camera.toml", "--height", "350", "-o", cli, "--quiet")
    assert r.returncode == 0, r.stderr
    py = tmp_path / "py.tif"
    gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", 350, py)
    assert filecmp.cmp(cli, py, shallow=False)


def test_a_bad_input_raises_its_kind_with_the_commands_message(scene, tmp_path):
    bad = tmp_path / "dem.tif"
    bad.write_bytes(b"II*\x00" + b"\x00" * 60)
    out = tmp_path / "out.tif"
    r = command("rectify", "--image", scene / "scan.tif", "--camera", scene / "camera.toml", "--dem", bad, "-o", out)
    assert r.returncode == 1
    said = r.stderr.strip().removeprefix("gcm-ortho: error: ")
    with pytest.raises(gcm_ortho.InputError) as e:
        gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", bad, out)
    assert str(e.value) == said
    assert str(bad) in str(e.value)
    assert not out.exists()
    assert os.listdir(tmp_path) == ["dem.tif"]


def test_a_missing_file_is_an_os_error(scene, tmp_path):
    with pytest.raises(gcm_ortho.InputOutputError) as e:
        gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", tmp_path / "none.tif", tmp_path / "out.tif")
    assert isinstance(e.value, OSError)
    assert str(e.value) == f"{tmp_path / 'none.tif'}: no such file or folder"


def test_settings_are_refused_by_their_key(scene, tmp_path):
    out = tmp_path / "out.tif"
    args = (scene / "scan.tif", scene / "camera.toml", scene / "dem.tif", out)
    with pytest.raises(gcm_ortho.SettingError, match=r"^tile: 17 must be a multiple of 16 up to 4096$") as e:
        gcm_ortho.rectify(*args, tile=17)
    assert isinstance(e.value, ValueError)
    with pytest.raises(gcm_ortho.SettingError, match=r"^sparsty: not an option here \(the options: .*`sparsity`"):
        gcm_ortho.rectify(*args, sparsty=8)
    with pytest.raises(gcm_ortho.SettingError, match=r"^sparsity: invalid type"):
        gcm_ortho.rectify(*args, sparsity="eight")
    with pytest.raises(gcm_ortho.SettingError, match=r"^compress: "):
        gcm_ortho.rectify(*args, compress="rar")
    assert not out.exists()


def test_the_output_never_overwrites_an_input(scene):
    with pytest.raises(gcm_ortho.SettingError):
        gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif", scene / "dem.tif")
    # The DEM is still a DEM.
    assert gcm_ortho.read(scene / "dem.tif").data.dtype == np.float32


def test_doubtful_input_warns(scene, tmp_path):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        report = gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif", tmp_path / "out.png")
    texts = [str(w.message) for w in said if issubclass(w.category, gcm_ortho.GcmOrthoWarning)]
    assert any("GeoTIFF" in t for t in texts), texts
    assert any("GeoTIFF" in t for t in report["warnings"])


def test_progress_is_reported_throttled_and_to_the_end(scene, tmp_path):
    calls = []
    gcm_ortho.rectify(
        scene / "scan.tif", scene / "camera.toml", scene / "dem.tif", tmp_path / "out.tif",
        progress=lambda done, total, task: calls.append((done, total, task)), progress_interval=10.0,
    )
    # One at the end at least; within 10 s no more than a start and the end.
    assert 1 <= len(calls) <= 2, calls
    done, total, task = calls[-1]
    assert task == "rectify" and done == total > 0


def test_an_exception_in_the_callback_cancels_the_run(scene, tmp_path):
    out = tmp_path / "out.tif"

    def stop(done, total, task):
        raise RuntimeError("enough")

    with pytest.raises(RuntimeError, match="enough"):
        gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif", out, progress=stop, progress_interval=0.001, threads=1)
    assert os.listdir(tmp_path) == []


def test_ctrl_c_from_a_thread_cancels_and_leaves_nothing(tmp_path):
    big = tmp_path / "big"
    r = command("synth", "--out", big, "--size", "6000x6000", "--seed", "4", "--quiet")
    assert r.returncode == 0, r.stderr
    before = sorted(os.listdir(big))
    started = threading.Event()
    main = threading.main_thread().ident

    def on_progress(done, total, task):
        if 0 < done < total:
            started.set()

    def interrupt():
        started.wait(60)
        signal.pthread_kill(main, signal.SIGINT)

    threading.Thread(target=interrupt, daemon=True).start()
    with pytest.raises(KeyboardInterrupt):
        gcm_ortho.rectify(
            big / "scan.tif", big / "camera.toml", big / "dem.tif", big / "out.tif",
            progress=on_progress, progress_interval=0.01, threads=1, compress="zstd", level=9,
        )
    assert started.is_set()
    assert sorted(os.listdir(big)) == before


def test_the_gil_is_released_while_a_run_works(scene, tmp_path):
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)
            stop.wait(0.001)

    t = threading.Thread(target=count)
    t.start()
    gcm_ortho.rectify(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif", tmp_path / "out.tif", threads=1, resample="lanczos3")
    stop.set()
    t.join()
    assert len(ticks) > 20


def test_a_window_is_the_single_runs_pixels(scene, single):
    plan = gcm_ortho.plan(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif")
    assert (plan.width, plan.height, plan.tile, plan.tiles_across, plan.tiles_down) == (1460, 1222, 256, 6, 5)
    assert plan.crs.startswith("EPSG:")
    whole = gcm_ortho.read(single)
    assert whole.data.shape == (3, 1222, 1460)
    # An inner window, and one at the grid's right and bottom edges.
    for col, row, w, h in [(2, 1, 2, 3), (4, 3, 2, 2)]:
        win = gcm_ortho.render_window(plan, col, row, w, h)
        assert (win.col, win.row) == (col * 256, row * 256)
        rows = slice(win.row, win.row + win.data.shape[1])
        cols = slice(win.col, win.col + win.data.shape[2])
        assert win.data.shape[1:] == whole.data[:, rows, cols].shape[1:]
        assert np.array_equal(win.data, whole.data[:, rows, cols])
        assert np.array_equal(win.mask, whole.mask[rows, cols])
    assert 0.5 < whole.mask.mean() < 1.0


def test_pieces_assemble_into_the_single_run(scene, single, tmp_path):
    plan = gcm_ortho.plan(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif")
    pieces = []
    for i, (col, row, w, h) in enumerate(plan.windows(tiles=4)):
        piece = tmp_path / f"piece{i}.tif"
        gcm_ortho.render_window(plan, col, row, w, h, out=piece)
        pieces.append(piece)
    assert len(pieces) == 4
    gcm_ortho.assemble(pieces, tmp_path / "whole.tif")
    assert filecmp.cmp(single, tmp_path / "whole.tif", shallow=False)


def render_piece(plan, window, folder):
    col, row, w, h = window
    out = os.path.join(folder, f"piece_{col}_{row}.tif")
    gcm_ortho.render_window(plan, col, row, w, h, out=out, threads=1)
    return out


def test_dask_workers_make_the_single_runs_file(scene, single, tmp_path):
    from dask.distributed import Client, LocalCluster

    plan = gcm_ortho.plan(scene / "scan.tif", scene / "camera.toml", scene / "dem.tif")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, Client(cluster) as client:
        futures = client.map(render_piece, [plan] * 9, list(plan.windows(tiles=2)), [str(tmp_path)] * 9)
        pieces = client.gather(futures)
    assert len(set(pieces)) == 9
    gcm_ortho.assemble(pieces, tmp_path / "whole.tif")
    assert filecmp.cmp(single, tmp_path / "whole.tif", shallow=False)


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    d = tmp_path_factory.mktemp("block")
    r = command(
        "synth", "--out", d, "--camera", "digital", "--relief", "urban", "--size", "900x600", "--dem-posting", "1",
        "--scale", "8000", "--block", "2x2", "--quiet",
    )
    assert r.returncode == 0, r.stderr
    return d


def test_a_mosaic_is_the_commands(block, tmp_path):
    r = command("mosaic", "manifest.toml", "-o", tmp_path / "cli.tif", "--quiet", cwd=block)
    assert r.returncode == 0, r.stderr
    report = gcm_ortho.mosaic(block / "manifest.toml", tmp_path / "py.tif")
    assert filecmp.cmp(tmp_path / "cli.tif", tmp_path / "py.tif", shallow=False)
    assert report["width"] > 0 and len(report["images"]) == 4


def test_a_mosaics_windows_on_dask_make_the_whole(block, tmp_path):
    from dask.distributed import Client, LocalCluster

    whole = tmp_path / "whole.tif"
    gcm_ortho.mosaic(block / "manifest.toml", whole)
    plan = gcm_ortho.mosaic_plan(block / "manifest.toml", tmp_path / "plan.json")
    assert plan.kind == "mosaic" and plan.tile == 256
    windows = list(plan.windows(tiles=2))
    assert len(windows) > 1
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, Client(cluster) as client:
        pieces = client.gather(client.map(render_piece, [plan] * len(windows), windows, [str(tmp_path)] * len(windows)))
    gcm_ortho.assemble(pieces, tmp_path / "joined.tif")
    assert np.array_equal(gcm_ortho.read(whole).data, gcm_ortho.read(tmp_path / "joined.tif").data)
    assert filecmp.cmp(whole, tmp_path / "joined.tif", shallow=False)


def test_the_package_installs_the_command(tmp_path):
    exe = INSTALLED
    assert os.access(exe, os.X_OK)
    r = subprocess.run([exe, "--version"], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.startswith("gcm-ortho ")
    r = subprocess.run([exe, "rectify", "--image", tmp_path / "none.tif", "--camera", "c.toml", "--height", "0", "-o", tmp_path / "o.tif"], capture_output=True, text=True)
    assert r.returncode == 1
    assert r.stderr.startswith("gcm-ortho: error: ") and "none.tif" in r.stderr


def test_a_dem_from_points_is_the_commands(tmp_path):
    r = command("synth", "--out", tmp_path, "--points", "20000", "--quiet")
    assert r.returncode == 0, r.stderr
    points = tmp_path / "points.las"
    r = command("grid", points, "-o", tmp_path / "cli.tif", "--gsd", "2", "--crs", "EPSG:32631", "--class", "0", "--method", "idw", "--quiet")
    assert r.returncode == 0, r.stderr
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        report = gcm_ortho.grid(points, tmp_path / "py.tif", 2, crs="EPSG:32631", classes=[0], method="idw")
    assert filecmp.cmp(tmp_path / "cli.tif", tmp_path / "py.tif", shallow=False)
    assert 19000 < report["points_used"] < 20000
    # What the command warns of, Python warns of.
    assert [str(w.message) for w in said if issubclass(w.category, gcm_ortho.GcmOrthoWarning)] == report["warnings"]
    with pytest.raises(gcm_ortho.SettingError, match=r"^method: "):
        gcm_ortho.grid(points, tmp_path / "x.tif", 2, crs="EPSG:32631", method="kriging")


def test_a_dsm_from_a_stereo_pair_is_the_commands(tmp_path):
    r = command("synth", "--out", tmp_path, "--camera", "rpc", "--stereo", "0.5", "--size", "400x400", "--bands", "1", "--off-nadir", "5", "--quiet")
    assert r.returncode == 0, r.stderr
    sides = dict(left_rpc=tmp_path / "left_RPC.TXT", right_rpc=tmp_path / "right_RPC.TXT")
    r = command(
        "dem", "--left", tmp_path / "left.tif", "--right", tmp_path / "right.tif", "--left-rpc", sides["left_rpc"],
        "--right-rpc", sides["right_rpc"], "-o", tmp_path / "cli.tif", "--gsd", "2", "--quiet",
    )
    assert r.returncode == 0, r.stderr
    report = gcm_ortho.dem(tmp_path / "left.tif", tmp_path / "right.tif", tmp_path / "py.tif", 2, **sides)
    assert filecmp.cmp(tmp_path / "cli.tif", tmp_path / "py.tif", shallow=False)
    assert report["matched_share"] > 0.8
    with pytest.raises(gcm_ortho.SettingError, match=r"^window: 4 is not an odd side"):
        gcm_ortho.dem(tmp_path / "left.tif", tmp_path / "right.tif", tmp_path / "x.tif", 2, window=4, **sides)


def test_a_scan_truncated_underneath_fails_the_run_not_python(tmp_path):
    r = command("synth", "--out", tmp_path, "--size", "5000x5000", "--seed", "6", "--quiet")
    assert r.returncode == 0, r.stderr
    scan, out = tmp_path / "scan.tif", tmp_path / "out.tif"
    cut = []

    def truncate_once_started(done, total, task):
        if 0 < done < total and not cut:
            with open(scan, "r+b") as f:
                f.truncate(4096)
            cut.append(done)

    with pytest.raises(gcm_ortho.InputError, match="truncated") as e:
        gcm_ortho.rectify(
            scan, tmp_path / "camera.toml", tmp_path / "dem.tif", out,
            progress=truncate_once_started, progress_interval=0.01, threads=1, compress="zstd", level=9,
        )
    assert cut, "the run ended before the scan was cut"
    assert str(scan) in str(e.value)
    assert not out.exists()
    assert sorted(os.listdir(tmp_path)) == ["camera.toml", "checkpoints.csv", "dem.tif", "scan.tif", "truth.tif"]
    # The interpreter goes on, and so do runs.
    other = tmp_path / "again"
    assert command("synth", "--out", other, "--size", "600x500", "--seed", "2", "--quiet").returncode == 0
    gcm_ortho.rectify(other / "scan.tif", other / "camera.toml", other / "dem.tif", other / "o.tif")
