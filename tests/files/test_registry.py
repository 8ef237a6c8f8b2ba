"""The registry of file formats: every suffix to one format object, and a path's format."""

import pytest

from snapcorr.files.registry import (
    FILE_FORMATS,
    FORMATS,
    format_by_suffix,
    format_of,
    input_files,
)


def test_every_suffix_names_a_registered_format_of_that_suffix():
    for suffix, name in FORMATS.items():
        assert suffix in FILE_FORMATS[name].suffixes
        assert format_by_suffix(suffix.upper()) is FILE_FORMATS[name]


def test_the_suffixes_snapcorr_reads_and_writes():
    assert sorted(FORMATS) == [".exr", ".hdr", ".nc", ".npy", ".tif", ".tiff", ".zarr"]


def test_each_format_names_how_every_target_is_marked(tmp_path):
    for fmt in FILE_FORMATS.values():
        targets = fmt.targets(tmp_path / f"c{fmt.suffixes[0]}")
        assert targets[0] == tmp_path / f"c{fmt.suffixes[0]}"
        assert len(fmt.marked_as) == len(targets), fmt.name
    assert FILE_FORMATS["envi"].targets(tmp_path / "c.hdr")[1] == tmp_path / "c.raw"
    assert FILE_FORMATS["npy"].role(1) == "sidecar"


def test_an_envi_data_file_names_its_header(tmp_path):
    (tmp_path / "c.hdr").write_text("ENVI\n")
    fmt, main, data = format_of(tmp_path / "c.img")
    assert (fmt.name, main, data) == ("envi", tmp_path / "c.hdr", tmp_path / "c.img")
    with pytest.raises(ValueError, match="has no header"):
        format_of(tmp_path / "d.raw")


def test_an_unknown_suffix_is_refused_with_the_known_ones(tmp_path):
    assert format_by_suffix(".png") is None
    with pytest.raises(ValueError, match=r"unknown frame format '\.png'.*\.zarr"):
        format_of(tmp_path / "x.png", "frame")


def _written_files(folder):
    """Every file and folder in ``folder``, as a write left them (a Zarr store counted once)."""
    return sorted(p for p in folder.iterdir())


@pytest.mark.parametrize("upper", [False, True], ids=["lower", "upper"])
@pytest.mark.parametrize("fmt", sorted(FILE_FORMATS))
def test_every_file_a_write_makes_belongs_to_the_input(tmp_path, fmt, upper):
    """Whatever a write of each registered format leaves on disk (found by listing the
    folder, not from the format's own list of targets) is a file of that input, under every
    suffix the format is known by."""
    import numpy as np

    from snapcorr.cube import make_cube
    from snapcorr.files.api import write_cube

    cube = make_cube(np.ones((3, 4, 2), np.float32), [500.0, 600.0])
    for suffix in FILE_FORMATS[fmt].suffixes:
        name = f"C{suffix.upper()}" if upper else f"c{suffix}"
        folder = tmp_path / name.replace(".", "_")
        folder.mkdir()
        path = write_cube(cube, folder / name)
        on_disk = _written_files(folder)
        assert path in on_disk
        assert set(on_disk) <= set(input_files(path)), (name, on_disk)


def test_an_envi_input_takes_in_every_data_file_its_readers_may_use(tmp_path):
    hdr = tmp_path / "c.hdr"
    hdr.write_text("ENVI\n")
    for name in ("c.img", "c.BIL", "c.dat"):
        (tmp_path / name).write_bytes(b"\0")
    (tmp_path / "c.toml").write_text("")  # not an ENVI data name
    got = input_files(hdr)
    assert got[0] == hdr
    assert {tmp_path / n for n in ("c.img", "c.BIL", "c.dat")} <= set(got)
    assert tmp_path / "c.toml" not in got
    # a data file given instead of its header brings the header (also one not yet there)
    assert tmp_path / "d.hdr" in input_files(tmp_path / "d.IMG")


def test_an_input_of_no_registered_format_is_its_own_only_file(tmp_path):
    """A lens or sensor TOML, a PNG: no format, nothing else belongs to it, and no error
    (the commands' inputs are not all cubes). Reading or writing it as a cube is refused
    with the suffixes snapcorr knows."""
    for name in ("lens.toml", "plot.png", "noext", "x.xyz"):
        assert input_files(tmp_path / name) == [tmp_path / name]
    with pytest.raises(ValueError, match=r"unknown cube format '\.xyz'.*\.exr, \.hdr"):
        format_of(tmp_path / "x.xyz")
    with pytest.raises(ValueError, match=r"unknown cube format '\(none\)'"):
        format_of(tmp_path / "noext")


def _snapcorr_imports(path, here):
    """The snapcorr modules ``path`` (module ``here``, dotted) imports, lazily too."""
    import ast

    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = here.split(".")[:-node.level]
            name = ".".join(base + ([node.module] if node.module else []))
            out |= {f"{name}.{a.name}" if node.module is None else name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("snapcorr"):
            out.add(node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("snapcorr")}
    return out


def test_the_files_package_builds_on_the_data_model_only():
    """files/ imports nothing above it: of cube/ only the data model (model, attrs,
    derived), and none of correct/, calibrate/, the command line; no module of files/
    imports itself through others."""
    from pathlib import Path

    import snapcorr.files

    folder = Path(snapcorr.files.__file__).parent
    graph = {}
    for path in sorted(folder.glob("*.py")):
        here = f"snapcorr.files.{path.stem}" if path.stem != "__init__" else "snapcorr.files"
        graph[here] = _snapcorr_imports(path, here if path.stem != "__init__" else here + ".x")
    allowed = {"snapcorr", "snapcorr.__version__", "snapcorr._validation", "snapcorr._lazy",
               "snapcorr._threads",
               "snapcorr.cube.model", "snapcorr.files.attrs", "snapcorr.cube.derived"}
    above = sorted(f"{m} imports {d}" for m, deps in graph.items() for d in deps
                   if not d.startswith("snapcorr.files") and d not in allowed)
    assert not above, above

    def reach(start):
        seen, todo = set(), [start]
        while todo:
            for d in graph.get(todo.pop(), ()):
                if d in graph and d not in seen:
                    seen.add(d)
                    todo.append(d)
        return seen

    cycles = sorted(m for m in graph if m != "snapcorr.files" and m in reach(m))
    assert not cycles, cycles
