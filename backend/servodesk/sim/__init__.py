"""Simulated drives: the plant, the drive engine and the fieldbus front-ends that serve them.

``plant`` is the physics (pure Python), ``engine`` the CiA 402 drive behaviour (no bus code),
``canopen_device`` and ``od_build`` the CANopen device side, ``runner`` steps drives on the
wall clock, ``bus`` starts a set of drives on one python-can bus.
"""
