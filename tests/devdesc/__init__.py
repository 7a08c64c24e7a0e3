"""Tests of device-description import and export (EDS/DCF, ESI, XDD)."""
