"""The bag package's one error: a bag that cannot be written or read."""

from __future__ import annotations


class BagError(RuntimeError):
    """A bag cannot be written or read: says which path and what is wrong."""
