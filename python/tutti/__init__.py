"""tutti as a Python wheel: the `tutti` command, the RTAPI's C library and header, and the
Python modules `tutti_rtapi` (a component's calls) and `tutti_ctl` (a run's control).

The wheel carries the prebuilt files below; `tutti_rtapi` loads the library from here before
looking for an installed one (docs/install.md, "The Python wheel").
"""

import os

__all__ = ["bin_path", "include_dir", "lib_dir", "library"]

_HERE = os.path.dirname(os.path.abspath(__file__))


def bin_path():
    """The `tutti` executable this wheel carries."""
    return os.path.join(_HERE, "bin", "tutti")


def lib_dir():
    """The directory of `librtapi.so.0` and `libOpalOrchestra.so`."""
    return os.path.join(_HERE, "lib")


def include_dir():
    """The directory of `RTAPI.h` (for a C build: `-I` this, link `library()`)."""
    return os.path.join(_HERE, "include")


def library():
    """The path of the bundled `librtapi.so.0`."""
    return os.path.join(lib_dir(), "librtapi.so.0")
