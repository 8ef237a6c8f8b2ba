"""Registries say what they hold, once: each name is unique in the package, and the earlier
names stay as aliases of the same objects."""

import importlib
import importlib.util
import json
import pkgutil
from pathlib import Path

import pytest

import snapcorr
from snapcorr import _names, budget, demo, optics, simulate
from snapcorr.budget import signal
from snapcorr.calibrate.lens import joint_fit
from snapcorr.optics import lens, mean, profiles

#: Earlier name -> the registry it now names, (module, old, new).
ALIASES = [
    (_names, "SHIFT_METHODS", "MEAN_SHIFT_METHOD_NAMES"),
    (mean, "METHODS", "MEAN_SHIFT_METHODS"),
    (mean, "MODELS", "CORRECTION_MODELS"),
    (optics, "METHODS", "MEAN_SHIFT_METHODS"),
    (optics, "MODELS", "CORRECTION_MODELS"),
    (profiles, "PROFILES", "FILTER_PROFILES"),
    (optics, "PROFILES", "FILTER_PROFILES"),
    (signal, "PROFILES", "SIGNAL_PROFILES"),
    (budget, "PROFILES", "SIGNAL_PROFILES"),
    (budget, "MODELS", "CORRECTION_MODELS"),
    (simulate, "METHODS", "ILLUMINATION_METHODS"),
    (demo, "MODELS", "DEMO_MODELS"),
    (lens, "PUPILS", "PUPIL_RADIANCE_MODELS"),
    (joint_fit, "MODELS", "CIRCLE_MODELS"),
]


@pytest.mark.parametrize(("module", "old", "new"), ALIASES,
                         ids=[f"{m.__name__}.{old}" for m, old, _ in ALIASES])
def test_an_earlier_registry_name_is_the_same_object(module, old, new):
    assert getattr(module, old) is getattr(module, new)


def test_the_registries_hold_what_they_held():
    assert tuple(mean.MEAN_SHIFT_METHODS) == _names.MEAN_SHIFT_METHOD_NAMES
    assert mean.CORRECTION_MODELS is _names.CORRECTION_MODELS
    assert set(signal.SIGNAL_PROFILES) < set(profiles.FILTER_PROFILES)
    assert demo.DEMO_MODELS == ("asymptotic", "ideal", "vignetted")


def test_each_registry_name_holds_one_thing_in_the_package():
    """A registry's name (``*_METHODS``, ``*_MODELS``, ``*_PROFILES``) bound in two modules
    is one object re-exported, never two registries under one name."""
    held = {}
    for info in pkgutil.walk_packages(snapcorr.__path__, "snapcorr."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if name.endswith(("_METHODS", "_MODELS", "_PROFILES")) and name.isupper():
                held.setdefault(name, {})[id(value)] = f"{info.name}.{name}"
    clashes = {name: sorted(where.values()) for name, where in held.items() if len(where) > 1}
    assert not clashes, clashes


#: Every public name each module defined or listed in ``__all__`` in release 0.1, before its
#: modules moved to their rooms (module -> names).
EARLIER = json.loads((Path(__file__).parent / "data" / "public_names_0.1.json").read_text())

#: Every module's ``__all__`` as the next release (0.2) has it, written by
#: ``tests/data/make_public_names.py``.
NEWEST = json.loads((Path(__file__).parent / "data" / "public_names_0.2.json").read_text())

RECORDED = [("0.1", module) for module in sorted(EARLIER)] + [
    ("0.2", module) for module in sorted(NEWEST)]


@pytest.mark.parametrize(("release", "module"), RECORDED,
                         ids=[f"{release}-{module}" for release, module in RECORDED])
def test_every_recorded_public_name_still_imports_from_its_module(release, module):
    found = importlib.import_module(module)
    names = (EARLIER if release == "0.1" else NEWEST)[module]
    missing = [name for name in names if not hasattr(found, name)]
    assert not missing, missing


def _recorder():
    spec = importlib.util.spec_from_file_location(
        "make_public_names", Path(__file__).parent / "data" / "make_public_names.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_no_public_name_goes_unrecorded():
    """A name in a module's ``__all__`` is public: it is recorded, so that a later change
    which drops it fails the test above instead of breaking a user's import."""
    now = _recorder().public_names()
    unrecorded = {module: sorted(set(names) - set(NEWEST.get(module, ())))
                  for module, names in now.items()}
    unrecorded = {module: names for module, names in unrecorded.items() if names}
    assert not unrecorded, ("public names not in tests/data/public_names_0.2.json (record "
                            f"them with `python tests/data/make_public_names.py 0.2`): "
                            f"{unrecorded}")
