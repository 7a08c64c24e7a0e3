"""The physics both sides share (issue 51 item 4): the plant (rigid or two-mass mechanics with
friction), the drive's servo loop, the fused tick loop that steps them together, the profile
position set-point generator, the replay of a recorded move, and the plant file format.

The simulated drive (``servodesk.sim``, the device side) runs them as its motor and control
loop; the tuning (``servodesk.services.tuning*``) runs the same code to predict a move before
it sends it. Before this package the tuning imported them from ``sim``, so the device side was
also a library of the master's. Nothing here imports a link, a service, the web layer or the
device side (import-linter, pyproject.toml).
"""
