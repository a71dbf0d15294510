"""Reporting: figures (``plots``), atomic output writing (``outputs``) and provenance
(``provenance``: the inputs and versions written beside every product)."""
