"""Links: one module per fieldbus, each a :class:`~servodesk.links.base.DriveLink`.

Only this package imports bus libraries (python-can, canopen, pysoem, sockets).
"""

from servodesk.links.base import DriveLink, LinkEvent, LinkParams, ObjectAccess
from servodesk.links.registry import LinkRegistry, registry

__all__ = ["DriveLink", "LinkEvent", "LinkParams", "LinkRegistry", "ObjectAccess", "registry"]
