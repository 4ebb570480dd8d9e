"""Exports of a posed layout for other tools: the whole layout as one CAD assembly
(:mod:`rgmcad.export.assembly`)."""

from rgmcad.export.assembly import EXPORT_SUFFIXES, export_layout

__all__ = ["EXPORT_SUFFIXES", "export_layout"]
