"""servodesk: a web-based commissioning tool for CiA 402 servo drives.

The package is layered (see docs/architecture.md): ``domain`` is pure, ``links`` talks to
buses, ``sim`` is the device side, ``services`` hold sessions, ``api`` is FastAPI.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("servodesk")
except PackageNotFoundError:  # Running from a checkout without an install.
    __version__ = "0.0.0+local"

__all__ = ["__version__"]
