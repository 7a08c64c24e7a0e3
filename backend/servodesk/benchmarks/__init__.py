"""Benchmarks that ship with the package, so that ``servodesk bench ...`` runs them anywhere."""
