"""Write ``public_names_<version>.json``: every module's ``__all__`` as this version has it.

Run from the repository's top after a release's names are settled::

    python tests/data/make_public_names.py 0.2

``tests/test_names.py`` then checks that every name recorded still imports from its module,
and that no module lists a name in ``__all__`` that the newest record lacks (a new public
name is recorded on purpose, not by accident).
"""

import importlib
import json
import pkgutil
import sys
from pathlib import Path

import snapcorr


def public_names():
    """``{module: sorted __all__}`` for every module of snapcorr that has an ``__all__``."""
    names = {"snapcorr": sorted(snapcorr.__all__)}
    for info in pkgutil.walk_packages(snapcorr.__path__, "snapcorr."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        if hasattr(module, "__all__"):
            names[info.name] = sorted(module.__all__)
    return dict(sorted(names.items()))


if __name__ == "__main__":
    version = sys.argv[1]
    out = Path(__file__).parent / f"public_names_{version}.json"
    out.write_text(json.dumps(public_names(), indent=1) + "\n")
    print(f"wrote {out}: {sum(map(len, public_names().values()))} names")
