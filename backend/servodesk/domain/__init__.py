"""Pure domain model: addresses, CiA 301 data types, profiles, the CiA 402 state machine.

Nothing here imports a bus library, FastAPI, or does I/O beyond reading profile files.
"""
