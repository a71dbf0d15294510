"""orbits — the synthetic world of the Kiev 2012 seminar (and an astropy WGS84 mode)."""
