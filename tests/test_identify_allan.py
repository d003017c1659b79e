"""The Allan noise fit (rlgsim.estimators.identify.allan_noise) against independent references:
allantools' own noise generators (Kasdin power-law noise) and allantools' Allan deviation,
the analytic Allan variance of IEEE Std 952-1997 Annex C, and the simulator's pulse counter —
many seeds, the recovered values inside their 95 % intervals at about the nominal rate."""

from __future__ import annotations

import math
import pathlib
import sys
import tomllib

import allantools
import numpy as np
import pytest

from rlgsim.estimators.identify.allan_noise import DECORRELATED, fit_allan

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import identify_truth as IT  # noqa: E402

K_PULSES_PER_ARCSEC = 2.14            # trplg_001's counter
N_TRUE = 0.0008 * 60.0                # (°/h)·√s: trplg_001's ARW 0.0008 °/√h


def _counted(rate_deg_per_h: np.ndarray, k: float, f: float = 1.0) -> np.ndarray:
    """The rate as a counter that carries its fractional remainder reads it: whole pulses of
    1/k arcsec per sample (floor of the accumulated angle), back in °/h."""
    angle_pulses = np.cumsum(rate_deg_per_h / f * k)
    pulses = np.diff(np.floor(np.concatenate([[0.0], angle_pulses])))
    return pulses / k * f


def test_fit_with_q_free_recovers_q_n_k_of_allantools_noise():
    """White angle noise (quantisation-like Q), white rate noise N and rate random walk K from
    allantools' generators, 20 seeds: Q, N, K inside their 95 % intervals in most records."""
    f, n = 1.0, 2 ** 16
    q_true, n_true, k_true = 0.3, 0.05, 2e-4        # arcsec, (°/h)√s, (°/h)/√s
    inside = {"q_arcsec": 0, "arw_deg_per_sqrt_h": 0, "rrw_deg_per_h_per_sqrt_h": 0}
    truth = {"q_arcsec": q_true, "arw_deg_per_sqrt_h": n_true / 60.0,
             "rrw_deg_per_h_per_sqrt_h": k_true * 60.0}
    seeds = range(20)
    for seed in seeds:
        np.random.seed(seed)                         # allantools.noise draws from numpy's global
        # allantools' white noise of PSD b0 at fs = 1 Hz has the variance b0/2; its random walk
        # of PSD b_minus2·f⁻² the steps of variance (2π)²·b_minus2/2: both scaled to unit steps
        angle = q_true * allantools.noise.white(n + 1, b0=2.0)           # arcsec, white phase
        y = np.diff(angle) * f                                           # °/h (arcsec/s)
        y += n_true * math.sqrt(f) * allantools.noise.white(n, b0=2.0)
        y += k_true / math.sqrt(f) * allantools.noise.brown(n, b_minus2=2.0 / (2 * math.pi) ** 2)
        res = fit_allan(y, f)
        assert not res.q_fixed
        for key, true in truth.items():
            lo, hi = res.intervals[key]
            inside[key] += lo <= true <= hi
    # nominal 95 %; the intervals neglect the correlation of neighbouring τ (approximate)
    for key, count in inside.items():
        assert count >= 15, (key, count)


def test_counter_quantisation_is_fixed_from_the_pulse_weight_and_arw_recovered():
    """A counted rate (2.14 pulses/arcsec at 1 Hz, white noise at trplg_001's ARW) for mean rates on and between whole pulse
    counts per sample: with the quantum given the ARW is inside its interval in most records
    and never off by more than 10 %; with Q fitted freely over every τ a rate near a whole
    number of pulses per sample trades the quantisation for white noise (the old fit)."""
    n = 72000
    inside, free_arw = 0, []
    cases = [(r0, s) for r0 in (0.0, 3.3, 9.7, 10.0, 12.6) for s in range(4)]
    for r0, seed in cases:
        np.random.seed(1000 + seed)
        rate = r0 + N_TRUE * allantools.noise.white(n, b0=2.0)
        y = _counted(rate, K_PULSES_PER_ARCSEC)
        res = fit_allan(y, 1.0, quantum_arcsec=1.0 / K_PULSES_PER_ARCSEC)
        assert res.q_fixed
        assert res.values["q_arcsec"] == pytest.approx(1.0 / K_PULSES_PER_ARCSEC / math.sqrt(12))
        arw = res.values["arw_deg_per_sqrt_h"]
        lo, hi = res.intervals["arw_deg_per_sqrt_h"]
        inside += lo <= 0.0008 <= hi
        assert arw == pytest.approx(0.0008, rel=0.10), (r0, seed)
        if r0 == 3.3:                 # 7.06 pulses per sample: the error held nearly constant
            free_arw.append(fit_allan(y, 1.0).values["arw_deg_per_sqrt_h"])
    assert inside >= 0.85 * len(cases)
    assert min(free_arw) > 1.3 * 0.0008          # the confusion the fixed quantum removes


def test_counted_quantisation_is_white_beyond_the_decorrelation_tau():
    """IEEE 952's quantisation term 3Q²/τ², Q = quantum/√12, holds for the counter once the
    angle noise has smeared the reading error over a pulse (exp(−2π²mσ_p²) ≤ DECORRELATED),
    and not below it for a rate near a whole pulse count per sample — why the fit with a fixed
    Q starts there. Checked on allantools' overlapping Allan variance of the counted rate less
    the exactly known white part."""
    n, k = 2 ** 17, K_PULSES_PER_ARCSEC
    q2 = (1.0 / k) ** 2 / 12.0
    sigma_p = N_TRUE / (1.0 / k)                                   # pulses per 1 s sample
    m_min = math.log(1 / DECORRELATED) / (2 * math.pi ** 2 * sigma_p ** 2)
    ratios_short, ratios_long = [], []
    for seed in range(6):
        rng = np.random.default_rng(seed)
        white = N_TRUE * rng.standard_normal(n)
        y = _counted(3.3 + white, k)            # 7.06 pulses per sample
        taus, ad_y, _, _ = allantools.oadev(y, rate=1.0, data_type="freq", taus="octave")
        taus_w, ad_w, _, _ = allantools.oadev(white, rate=1.0, data_type="freq", taus="octave")
        quant = (ad_y ** 2 - ad_w ** 2) / (3 * q2 / taus ** 2)
        ratios_short.append(quant[taus < m_min / 4][0])
        sel = (taus >= m_min) & (taus <= 512)
        ratios_long.append(quant[sel])
    assert np.mean(ratios_short) < 0.8                            # τ = 1 s: not 3Q²/τ²
    assert np.mean(np.concatenate(ratios_long)) == pytest.approx(1.0, abs=0.05)


def test_simulated_trplg_001_recording_gives_its_arw(tmp_path):
    """A 4.9 h recording of a trplg_001 gyro (its counter, ARW 0.0008 °/√h, bias instability
    0.002 °/h; no anomalies) through the law fit on the true network's temperatures: the ARW's
    95 % interval holds 0.0008 °/√h and Q is the counter's."""
    from rlgsim.sim import presets
    from rlgsim.lab.identify.law_fit import fit_laws
    from rlgsim.lab.identify.recording_data import read_recording
    from rlgsim.lab.identify.thermal_fit import build, twin_response
    th = IT.thermal_truth(tmp_path, {})
    d = IT.device_truth(tmp_path, th)
    rec = read_recording(IT.simulate(IT.scenario(tmp_path, d, seed=7), tmp_path / "r.h5"))
    net, probes = build(presets.load_thermal_file(str(th)).data)
    nodes, _ = twin_response(net, probes, rec.air_c, rec.power, rec.step_s)
    dev = tomllib.loads(d.read_text())
    noise = fit_laws(rec, nodes, net.node_names, dev).noise
    lo, hi = noise.intervals["arw_deg_per_sqrt_h"]
    assert lo <= dev["noise"]["gyro_arw_deg_per_sqrt_h"] <= hi, (lo, hi)
    assert noise.q_fixed
    assert noise.values["q_arcsec"] == pytest.approx(
        1.0 / dev["gyro"]["scale_factor_pulses_per_arcsec"] / math.sqrt(12))


def test_bad_quantum_is_refused():
    y = np.random.default_rng(0).standard_normal(4096)
    with pytest.raises(ValueError, match="quantum_arcsec"):
        fit_allan(y, 1.0, quantum_arcsec=0.0)


def test_bias_instability_of_the_simulators_flicker_through_the_counter():
    """Flicker of bias instability B = 0.002 °/h from the simulator's own generator
    (rlgsim.sim.sensors.noise.FlickerBank: Gauss–Markov processes over 2 s–10⁵ s, Keshner/Kasdin), white
    noise at trplg_001's ARW, counted at 2.14 pulses/arcsec, 20 h at 1 Hz, 20 channels: B and
    the ARW inside their 95 % intervals in most channels, the median B within 15 %."""
    from rlgsim.sim.sensors.noise import FlickerBank
    n, channels, b_true = 72000, 20, 0.002
    rng = np.random.default_rng(5)
    bank = FlickerBank(np.full(channels, b_true), 1.0, 2.0, 1e5, 2)
    flicker, _ = bank.block(bank.initial_state(rng), rng, n)
    in_b = in_n = 0
    b_hat = []
    for c in range(channels):
        y = _counted(10.0 + N_TRUE * rng.standard_normal(n) + flicker[:, c], K_PULSES_PER_ARCSEC)
        res = fit_allan(y, 1.0, quantum_arcsec=1.0 / K_PULSES_PER_ARCSEC)
        lo, hi = res.intervals["bi_deg_per_h"]
        in_b += lo <= b_true <= hi
        lo, hi = res.intervals["arw_deg_per_sqrt_h"]
        in_n += lo <= N_TRUE / 60.0 <= hi
        b_hat.append(res.values["bi_deg_per_h"])
    assert in_b >= 15 and in_n >= 17, (in_b, in_n)
    assert np.median(b_hat) == pytest.approx(b_true, rel=0.15)


def test_compiled_overlapping_adev_equals_allantools():
    """The fit's overlapping Allan deviation (allantools' phase and octave τ, the sum of squared
    second differences compiled, summed by numpy as allantools sums them) against
    ``allantools.oadev`` on white plus random-walk rate noise: the same τ, counts and
    deviations, bit for bit."""
    from rlgsim.estimators._allan_kernel import oadev_octave
    rng = np.random.default_rng(952)
    n = 2 ** 16
    y = rng.normal(0.0, 1.0, n) + np.cumsum(rng.normal(0.0, 0.01, n))
    y = y - y.mean()
    taus, adev, _, ns = allantools.oadev(y, rate=10.0, data_type="freq", taus="octave")
    got_t, got, got_n = oadev_octave(y, 10.0)
    np.testing.assert_array_equal(got_t, taus)
    np.testing.assert_array_equal(got_n, ns)
    np.testing.assert_array_equal(got, adev)
    short_t, _, _ = oadev_octave(y, 10.0, max_tau_s=100.0)
    np.testing.assert_array_equal(short_t, taus[taus <= 100.0])
