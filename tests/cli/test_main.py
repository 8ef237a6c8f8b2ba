"""The command line: help, version, the demo, and one-line errors instead of tracebacks."""

import re
import signal
import subprocess
import sys
import warnings

import numpy as np
import pytest

from snapcorr import Lens, __version__


def test_the_entry_point_exits_with_the_status_and_one_line():
    """The real entry point, in a process of its own (the other tests run the same ``main``
    in-process): ``python -m snapcorr`` prints the version, and an error is one line on
    stderr, no traceback, with a non-zero exit status."""
    res = subprocess.run([sys.executable, "-m", "snapcorr", "--version"], capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0 and res.stdout == f"snapcorr {__version__}\n" and not res.stderr
    res = subprocess.run([sys.executable, "-m", "snapcorr", "shift", "--lens", "nope",
                          "--f-number", "2", "--cra", "1"], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 1 and not res.stdout and "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("snapcorr shift: error: no bundled lens")


def test_in_process_runs_leave_no_global_state(cli, monkeypatch):
    """``main(argv)`` called from Python gives the caller's process back as it was: signal
    handlers, warning filters, hooks (``cli`` checks this after every run), also after an
    interruption; and the check itself notices a handler left behind."""
    from snapcorr.cli import shift

    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    filters = list(warnings.filters)
    for args in (["shift", "--f-number", "1.4", "--cra", "0"], ["shift", "--f-number", "0"],
                 ["shift", "--lens", "nope", "--f-number", "2", "--cra", "1"], ["--help"]):
        cli(*args)

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(shift, "run", interrupted)
    res = cli("shift", "--f-number", "2", "--cra", "1")
    assert res.returncode == 130 and "interrupted" in res.stderr
    assert {s: signal.getsignal(s) for s in handlers} == handlers
    assert warnings.filters == filters

    def leaky(args):
        # a hook of its own (a handler of SIGINT, SIGTERM or SIGHUP the command sets is
        # undone when it ends, with the handlers it took over)
        sys.excepthook = lambda *_: None
        return 0

    monkeypatch.setattr(shift, "run", leaky)
    hook = sys.excepthook
    try:
        with pytest.raises(AssertionError, match="left global state behind"):
            cli("shift", "--f-number", "2", "--cra", "1")
    finally:
        sys.excepthook = hook


def test_version_and_help(cli):
    res = cli("--version")
    assert res.returncode == 0 and __version__ in res.stdout
    res = cli("--help")
    assert res.returncode == 0 and "a session" in res.stdout and "snapcorr demo" in res.stdout
    assert len(res.stdout.splitlines()) < 45  # the commands and one session, not every example
    for sub in ("demo", "shift", "flatfield", "calibrate", "correct", "budget"):
        res = cli(sub, "--help")
        assert res.returncode == 0 and "examples:" in res.stdout
        # each subcommand shows its own examples only
        shown = set(re.findall(r"^\s+snapcorr (\w+)", res.stdout.split("examples:")[1], re.M))
        assert shown == {sub}, (sub, shown)
        if sub == "correct":  # continued lines keep their backslash and break, ready to paste
            assert "--f-number 1.4 \\\n      --out scene_corrected.nc" in res.stdout


def test_every_example_in_the_help_parses():
    """The examples of --help use options that exist, with values they accept."""
    import shlex

    from snapcorr.cli import EXAMPLES, WORKFLOW, build_parser

    parser = build_parser()
    text = re.sub(r"\s*\\\n\s*", " ", "\n".join([WORKFLOW, *EXAMPLES.values()]))
    # a command, then (after two or more spaces) what it does
    commands = [re.split(r"\s{2,}", line.strip())[0] for line in text.splitlines()
                if line.strip().startswith("snapcorr ")]
    assert len(commands) > 20
    for command in commands:
        try:
            parser.parse_args(shlex.split(command)[1:])
        except SystemExit:
            pytest.fail(f"does not parse: {command}")


def test_every_option_has_help_text():
    from snapcorr.cli import build_parser

    parser = build_parser()
    subs = next(a for a in parser._actions if a.dest == "command").choices
    for name, sub in subs.items():
        for action in sub._actions:
            if action.dest != "help":
                assert action.help, f"snapcorr {name} {action.option_strings or action.dest}"


@pytest.mark.examples  # the README's first command, end to end (about 20 s)
def test_demo_writes_figure_table_and_summary(tmp_path, cli):
    res = cli("demo", "--out", tmp_path / "out")
    assert res.returncode == 0, res.stderr
    out = tmp_path / "out"
    assert (out / "mean_shift.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    table = np.loadtxt(out / "mean_shift.csv", delimiter=",", skiprows=1)
    assert table.shape[1] == 6 and np.all(np.isfinite(table))
    text = (out / "summary.txt").read_text()
    assert "f/#" in text and "vignetted" in text
    for name in ("calibration.png", "spectra.png", "maps.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"
    lens = Lens.load(out / "lens.toml")  # the profile calibrated from the simulated flats
    assert abs(lens.vignetting[0][0] / 7.4236 - 1) < 0.01
    assert abs(lens.vignetting[0][1] / 16.991 - 1) < 0.01
    # The paper's findings (Sec. 3.3-3.4), from the simulated experiment: at f/1.4 the
    # uncorrected spectra differ little, the ideal-aperture model over-corrects (worse than
    # none), the vignetting model aligns them best; at f/8 the two models agree.
    rows = {float(m.group(1)): [float(v) for v in m.groups()[1:]] for m in re.finditer(
        r"^\s+([\d.]+) r ([\d.]+), max ([\d.]+) r ([\d.]+), max ([\d.]+) "
        r"r ([\d.]+), max ([\d.]+)$", text, re.M)}
    assert set(rows) == {1.4, 2.0, 2.8, 4.0, 8.0}
    r_unc, e_unc, r_ideal, e_ideal, r_vig, e_vig = rows[1.4]
    assert e_ideal > e_unc > e_vig and r_vig > r_unc > r_ideal
    assert e_vig < 0.5 * e_unc
    assert rows[8.0][2:4] == rows[8.0][4:6]
    assert all(row[5] < row[1] for row in rows.values())  # vignetted beats uncorrected
    from snapcorr.demo import MARKER

    assert [p.name for p in out.glob(".*")] == [MARKER]  # no temporary files left behind
    assert "wrote" in res.stdout


def test_shift_table(cli):
    res = cli("shift", "--f-number", "1.4", "--cra", "0", "20")
    assert res.returncode == 0
    out = res.stdout
    assert "-8.954" in out and "vignetted" in out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["shift", "--f-number", "8", "--cra", "40"], "past the full cut-off at 27.06 deg"),
        (["shift", "--lens", "nope", "--f-number", "2", "--cra", "1"], "no bundled lens"),
        (["shift", "--lens", "missing.toml", "--f-number", "2", "--cra", "1"], "not found"),
        (["shift", "--f-number", "0", "--cra", "1"], "--f-number"),
        (["shift", "--f-number", "2", "--cra", "1", "--n-eff", "0.9"], "--n-eff"),
    ],
)
def test_foreseeable_mistakes_are_one_line_errors(cli, args, message):
    res = cli(*args)
    assert res.returncode != 0
    assert "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0]


def test_bad_lens_file_is_one_line_error(tmp_path, cli):
    bad = tmp_path / "bad.toml"
    bad.write_text("[lens]\nname = 'x'\n")
    res = cli("shift", "--lens", str(bad), "--f-number", "2", "--cra", "1")
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert "exit_pupil_mm" in res.stderr


def test_warning_is_one_line(tmp_path, cli):
    lens = tmp_path / "wide.toml"
    lens.write_text("[lens]\nname = 'wide'\nexit_pupil_mm = 21.0\n")
    res = cli("shift", "--lens", str(lens), "--f-number", "1.2", "--cra", "30")
    assert res.returncode == 0
    assert "warning" in res.stderr and "Traceback" not in res.stderr


@pytest.mark.parametrize("f", ["0.3", "1e-80", "1e-300"])
def test_f_numbers_below_the_physical_limit_are_one_line(cli, f):
    """f/1e-80 gave a shift of -700 nm, f/1e-300 NaN with exit 0: a working f-number below
    0.5 (a numerical aperture above 1) is refused wherever an f-number enters."""
    res = cli("shift", "--f-number", f, "--cra", "0", "10")
    assert res.returncode == 1 and "below the physical limit" in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("key, value, words", [
    ("pixel_pitch_um", "1e300", "no camera's pixel pitch"),
    ("pixel_pitch_um", "0.001", "no camera's pixel pitch"),
    ("n_eff", "7.0", "n_eff must be below 5"),
])
def test_sensor_numbers_outside_the_physics_are_refused(cli, tmp_path, key, value, words):
    table = {"name": '"t"', "layout": '"snapscan"', "pixel_pitch_um": "5.5",
             "cwl_nm": "[500.0, 600.0]", "fwhm_nm": "10.0", "n_eff": "1.7", key: value}
    path = tmp_path / "s.toml"
    path.write_text("[sensor]\n" + "".join(f"{k} = {v}\n" for k, v in table.items()))
    res = cli("sensor", path)
    assert res.returncode == 1 and words in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_overwrite_replaces_only_pngs_and_tomls_snapcorr_wrote(cli, tmp_path):
    """--plot PNGs and TOMLs that snapcorr did not write were replaced by --overwrite, against
    the help text. Its own are marked (PNG Software, the TOML's first line) and replaced."""
    from PIL import Image

    from snapcorr.data import sensor_path

    png, toml = tmp_path / "filters.png", tmp_path / "camera.toml"
    Image.new("RGB", (4, 4)).save(png)
    toml.write_text('[camera]\nnotes = "mine"\n')
    before = (png.read_bytes(), toml.read_text())
    res = cli("sensor", sensor_path("snapscan_vnir"), "--toml", toml, "--plot", png,
              "--overwrite")
    assert res.returncode == 1 and "snapcorr did not write" in res.stderr, res.stderr
    assert (png.read_bytes(), toml.read_text()) == before
    png.unlink()
    toml.unlink()
    for _ in range(2):  # written, then replaced: snapcorr's own
        res = cli("sensor", sensor_path("snapscan_vnir"), "--toml", toml, "--plot", png,
                  "--overwrite")
        assert res.returncode == 0, res.stderr
    assert toml.read_text().startswith("# written by snapcorr")
    with Image.open(png) as im:
        assert im.info["Software"].startswith("snapcorr")


def test_a_command_computes_without_importing_distributed(tmp_path):
    """dask, given no scheduler or one by name, imports dask.distributed at a process's first
    compute only to look for a client (0.3 s); a command without ``--scheduler`` runs on
    dask's threads named as a function, so it does not. Checked where the import would
    show: a process of its own, a chunked (dask) correction written to .zarr."""
    from snapcorr.cube import Sensor, make_cube, write_cube

    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 5), 10.0, 1.7)
    sensor.save(tmp_path / "sensor.toml")
    Lens.load("edmund_optics_16mm").save(tmp_path / "lens.toml")
    data = np.random.default_rng(0).random((30, 40, 5)).astype(np.float32)
    write_cube(make_cube(data, sensor.cwl_nm, name="reflectance"), tmp_path / "cube.zarr")
    script = """
import sys
from snapcorr.cli import main
rc = main(["correct", "cube.zarr", "--lens", "lens.toml", "--sensor", "sensor.toml",
           "--f-number", "2", "--out", "out.zarr", "--resample", "--quiet"])
print(rc, "dask" in sys.modules, "distributed" in sys.modules)
"""
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines()[-1] == "0 True False", res.stdout + res.stderr
    assert (tmp_path / "out.zarr").is_dir()
