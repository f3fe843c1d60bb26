"""Helpers shared by the property-based fuzz tests of file formats."""

from __future__ import annotations


def key_paths(node, prefix=(), max_items: int | None = None):
    """Every key path of a parsed YAML document (tuples of keys and list indices), the root first;
    ``max_items`` limits how many entries of each list are walked."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from key_paths(v, prefix + (k,), max_items)
    elif isinstance(node, list):
        for i, v in enumerate(node if max_items is None else node[:max_items]):
            yield from key_paths(v, prefix + (i,), max_items)
