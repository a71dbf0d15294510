"""Reproductions of published work: each package holds one paper's scenarios, its published
numbers (defined once, there) and its report. ``kiev2012``: the Kiev 2012 seminar."""
