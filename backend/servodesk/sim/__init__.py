"""Simulated drives: the plant, the drive engine and the fieldbus front-ends that serve them.

``plant`` is the physics (pure Python: rigid or two-mass mechanics, current loop, encoder),
``plantfile`` reads TOML plant files, ``servo`` is the drives' discrete servo loop and
``siggen`` its test signal generator (docs/tuning.md), ``engine`` the CiA 402 drive behaviour
(no bus code), ``canopen_device`` and ``od_build`` the CANopen device side, ``runner`` steps
drives on the wall clock, ``bus`` starts a set of drives on one python-can bus.
"""
