"""transfer_function and its inverse; coefficient files; compare; design."""
import numpy as np
import pytest

import fpss_stand as fs


def test_transfer_function_is_eq_1():
    c = fs.load_published("a-6-fpss1").alpha
    n = np.array([-3000.0, 0.0, 123.5, 2900.0])
    rad = c[0] + c[1] * n + c[2] * np.sin(c[3] * n + c[4]) + c[5] * np.sin(c[6] * n + c[7])
    assert np.allclose(fs.transfer_function(c, n), rad * 180 * 3600 / np.pi, rtol=1e-13, atol=1e-9)
    assert isinstance(fs.transfer_function(c, 10.0), float)


def test_inverse_round_trips_to_1e_9_counts():
    for name in ("a-6-fpss1", "a-1-fpss2"):
        cal = fs.load_published(name)
        for coeffs in (cal.alpha, cal.beta):
            n = np.linspace(-2500.0, 2500.0, 501)
            back = fs.inverse_transfer_function(coeffs, fs.transfer_function(coeffs, n), -4000, 4000)
            assert np.max(np.abs(back - n)) < 1e-9


def test_inverse_refuses_an_angle_out_of_reach():
    c = fs.load_published("a-6-fpss1").alpha
    with pytest.raises(ValueError, match="not reached"):
        fs.inverse_transfer_function(c, 1e7, -100, 100)


def test_published_sets_and_compare():
    names = fs.published_names()
    assert len(names) == 14 and "a-6-fpss1" in names
    same = fs.compare("a-6-fpss1", "a-6-fpss1")
    assert same["summary"]["alpha"]["max_abs_arcsec"] == 0.0
    diff = fs.compare("a-5-fpss1", "a-6-fpss1")
    assert diff["summary"]["alpha"]["max_abs_arcsec"] > 0
    assert len(diff["alpha"]["counts"]) == len(diff["alpha"]["diff_arcsec"]) > 100


def test_a_bad_coefficient_dict_names_the_key():
    j = dict(fs.load_published("a-6-fpss1").json)
    j["alpha"] = [1e9] + j["alpha"][1:]
    with pytest.raises(fs.InputError, match="alpha"):
        fs.compare(j, "a-6-fpss1")


def test_design_reaches_a_loose_target():
    d = fs.design(0.05, also_for=None)
    assert d["reached"] and d["offsets"] == len(d["offsets_deg"]) and d["samples_per_dwell"] > 0
    assert max(d["max_sigma_arcsec_pitch"], d["max_sigma_arcsec_yaw"]) <= 0.05
    assert {o["axis"] for o in d["offsets_deg"]} == {"pitch", "yaw"}
    # the command's blocks too, from the one builder: the inputs and the paper's grid on this bench
    assert d["inputs"]["extent_deg"] == 0.42 and d["inputs"]["robust_over"] == []
    assert d["paper_grid"]["bench_time_s"] > d["bench_time_s"]
    with pytest.raises(ValueError, match="target_sigma_arcsec"):
        fs.design(-1, also_for=None)
    with pytest.raises(TypeError, match="rate_deg"):
        fs.design(0.05, rate_deg=1)
