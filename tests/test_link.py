"""The link budget (docs/model.md §9) against closed forms, a hand computation and a Monte Carlo of OOK bits.

Every reference is written here in float64 from the textbook formula, not read from the module.
"""

import dataclasses
import math
from dataclasses import replace

import pytest
import torch
from conftest import ROOT, compose_config
from omegaconf import OmegaConf

from waterair.envs.rewards import Reward
from waterair.physics.channel import LinkGeometry, Transceiver, calm_sea_gain
from waterair.physics.link import (
    BACKGROUND_RADIANCE,
    RECEIVERS,
    LinkBudget,
    Receiver,
    background_power,
    bit_error_rate,
    detector_area,
    fec_power,
    link_performance,
    max_bit_rate,
    noise_variance,
    on_axis_intensity_per_watt,
    outage,
    q_at_ber,
    q_factor,
    received_power,
    snr,
)
from waterair.physics.optics import arrival_gain, departure_gain

Q = 1.602176634e-19  # C
K_B = 1.380649e-23  # J/K
F64 = torch.float64


def watts(*values):
    return torch.tensor(values, dtype=F64)


def test_q_of_six_gives_the_textbook_ber_and_the_fec_limit_its_q():
    for dtype in (torch.float32, F64):
        assert bit_error_rate(torch.tensor(6.0, dtype=dtype)).item() == pytest.approx(9.87e-10, rel=1e-3)
    assert bit_error_rate(watts(0.0)).item() == 0.5
    q_fec = q_at_ber(3.8e-3)
    assert 0.5 * math.erfc(q_fec / math.sqrt(2.0)) == pytest.approx(3.8e-3, rel=1e-9)
    assert q_fec == pytest.approx(2.67, abs=5e-3)


def test_shot_noise_limited_snr_is_responsivity_power_over_2qfb():
    # No background, no dark current, a load so cold and large that its noise is 1e-17 of the shot noise.
    apd = Receiver(gain=50.0, k_a=0.02, dark_current=0.0, temperature=1e-6, load_resistance=1e12, cutoff_hz=1e9)
    power, bandwidth = watts(1e-9, 1e-7, 1e-5), 1e6
    excess = 0.02 * 50.0 + 0.98 * (2.0 - 1.0 / 50.0)
    expected = 0.3 * power / (2.0 * Q * excess * bandwidth)
    assert torch.allclose(snr(power, 0.0, apd, bandwidth), expected, rtol=1e-9)
    # With σ_0 → 0, Q = I_1/σ_1 = sqrt(2 SNR): the "1" carries twice the average power.
    assert torch.allclose(q_factor(power, 0.0, apd, bandwidth) ** 2, 2.0 * expected, rtol=1e-6)


def test_thermal_noise_limited_snr_is_the_signal_power_over_4ktb_over_rl():
    # The signal's shot noise is 3e-8 (3e-7) of the 50 Ω load's thermal noise at 0.1 nW (1 nW).
    pin = Receiver(gain=1.0, dark_current=0.0, temperature=300.0, load_resistance=50.0, cutoff_hz=1e9)
    power, bandwidth = watts(1e-10, 1e-9), 2e6
    expected = (0.3 * power) ** 2 * 50.0 / (4.0 * K_B * 300.0 * bandwidth)
    assert torch.allclose(snr(power, 0.0, pin, bandwidth), expected, rtol=1e-6)
    assert torch.allclose(q_factor(power, 0.0, pin, bandwidth) ** 2, expected, rtol=1e-6)  # σ_1 = σ_0: Q² = SNR


@pytest.mark.parametrize("power", [2e-10, 4e-10, 5e-10])
def test_a_monte_carlo_of_ook_bits_agrees_with_the_ber_formula(power):
    """Gaussian currents at the budget's levels and σ's, cut at the threshold where both errors are Φ(−Q)."""
    apd = Receiver(gain=100.0, k_a=0.02, dark_current=0.0, load_resistance=1e4, cutoff_hz=1e9)
    background, bandwidth, bits = 2e-10, 5e6, 2_000_000
    p_r = watts(power)
    sigma_1 = noise_variance(2.0 * p_r, background, apd, bandwidth).sqrt().item()
    sigma_0 = noise_variance(0.0 * p_r, background, apd, bandwidth).sqrt().item()
    assert sigma_1 > 1.2 * sigma_0  # the levels' noises differ: the threshold is not halfway
    i_0 = 100.0 * 0.3 * background
    i_1 = i_0 + 100.0 * 0.3 * 2.0 * power
    threshold = (sigma_0 * i_1 + sigma_1 * i_0) / (sigma_0 + sigma_1)
    generator = torch.Generator().manual_seed(20)
    sent = torch.rand(bits, generator=generator, dtype=F64) < 0.5
    current = torch.where(sent, i_1, i_0) + torch.where(sent, sigma_1, sigma_0) * torch.randn(
        bits, generator=generator, dtype=F64
    )
    measured = ((current > threshold) != sent).double().mean().item()
    predicted = bit_error_rate(q_factor(p_r, background, apd, bandwidth)).item()
    standard_error = math.sqrt(predicted * (1.0 - predicted) / bits)
    assert 4e-4 < predicted < 0.1
    assert abs(measured - predicted) < 3.0 * standard_error  # 3 σ: a seeded draw, not a tuned one


def test_doubling_the_aperture_area_doubles_signal_and_background_but_not_the_thermal_noise():
    small = LinkBudget(optics=Transceiver(aperture_diameter=0.05))
    large = LinkBudget(optics=Transceiver(aperture_diameter=0.05 * math.sqrt(2.0)))
    gain = watts(0.01, 0.001)
    assert torch.allclose(received_power(gain, large), 2.0 * received_power(gain, small), rtol=1e-12)
    assert large.background_power == pytest.approx(2.0 * small.background_power, rel=1e-12)
    zero, r, b = watts(0.0), small.receiver, small.bandwidth
    thermal = 4.0 * K_B * r.temperature * b / r.load_resistance
    dark_shot = 2.0 * Q * r.dark_current * r.gain**2 * (r.k_a * r.gain + (1 - r.k_a) * (2 - 1 / r.gain)) * b
    background_shot_small = noise_variance(zero, small.background_power, r, b).item() - thermal - dark_shot
    background_shot_large = noise_variance(zero, large.background_power, r, b).item() - thermal - dark_shot
    assert background_shot_large == pytest.approx(2.0 * background_shot_small, rel=1e-9)
    assert noise_variance(zero, 0.0, dataclasses.replace(r, dark_current=0.0), b).item() == pytest.approx(thermal)


def test_the_gaussian_beam_carries_its_power_and_the_concentrator_collects_the_apertures():
    """∫ J_0 G_D dΩ over the upper hemisphere = P_t; G_A(0) · A_det = the aperture area (étendue)."""
    for divergence in (0.01, 0.05, 0.2):
        alpha = torch.linspace(0.0, math.pi / 2, 100_001, dtype=F64)
        profile = departure_gain(alpha, divergence, 520e-9) * 2.0 * math.pi * torch.sin(alpha)
        power = torch.trapezoid(profile, alpha).item() * on_axis_intensity_per_watt(divergence, 520e-9)
        assert power == pytest.approx(1.0, rel=divergence**2 / 2)  # paraxial: exact to (1 + ω_D²/4)
    for half_fov, n_c in ((0.17, 1.0), (0.3, 1.5)):
        peak = arrival_gain(torch.zeros(1, dtype=F64), half_fov, n_c).item()
        assert peak * detector_area(0.08, half_fov, n_c) == pytest.approx(math.pi * 0.08**2 / 4, rel=1e-12)


def _flat_sea_gain_by_hand():
    """G_0 of the default geometry: Snell point by bisection, Fresnel, Beer-Lambert, the paper's 1/d², G_A(0)."""
    depth, height, offset, n_w = 10.0, 10.0, 2.0, 1.33
    low, high = 0.0, offset
    for _ in range(200):
        x = 0.5 * (low + high)
        mismatch = n_w * x / math.hypot(x, depth) - (offset - x) / math.hypot(offset - x, height)
        low, high = (low, x) if mismatch > 0 else (x, high)
    d_w, d_a = math.hypot(x, depth), math.hypot(offset - x, height)
    cos1 = depth / d_w
    cos2 = math.sqrt(1.0 - (n_w * x / d_w) ** 2)
    r_s = (n_w * cos1 - cos2) / (n_w * cos1 + cos2)
    r_p = (cos1 - n_w * cos2) / (cos1 + n_w * cos2)
    fresnel = 1.0 - 0.5 * (r_s**2 + r_p**2)
    return math.exp(-0.151 * d_w) / (d_w + d_a) ** 2 * fresnel / math.sin(0.17) ** 2


def test_the_aligned_calm_sea_link_matches_the_hand_computation_in_the_docs():
    g_0 = _flat_sea_gain_by_hand()
    assert calm_sea_gain(LinkGeometry(), Transceiver()) == pytest.approx(g_0, rel=1e-9)
    # P_r = T_f P_t · 2/(π ω_D²) · (G_0 sin²ω_A) · π D²/4: the irradiance times the aperture (n_c = 1).
    omega_d2 = 0.05**2 + (520e-9 / (math.pi * 0.05)) ** 2
    by_hand = 0.9 * 0.05 * 2.0 / (math.pi * omega_d2) * g_0 * math.sin(0.17) ** 2 * math.pi * 0.05**2 / 4
    budget = LinkBudget()
    p_r = received_power(watts(g_0), budget).item()
    assert p_r == pytest.approx(by_hand, rel=1e-12)
    background = 5e-3 * 10.0 * 0.9 * math.pi * 0.05**2 / 4 * 2 * math.pi * (1 - math.cos(0.17))
    assert budget.background_power == pytest.approx(background, rel=1e-12)
    # The numbers docs/model.md §9 prints for this link, to the digits it prints them.
    link = link_performance(watts(g_0), budget)
    assert (round(p_r * 1e6, 2), round(budget.background_power * 1e6, 2)) == (11.99, 8.00)
    assert (round(link.q.item()), round(10 * math.log10(link.snr.item()), 1)) == (691, 56.4)
    assert link.max_bit_rate.item() == 8e7 and not link.outage.item()


def test_the_rate_at_the_fec_limit_has_exactly_the_fec_limits_ber_and_grows_with_power():
    apd = RECEIVERS["apd"]
    power = torch.logspace(-10, -6, 41, dtype=F64)
    rate = max_bit_rate(power, 8e-6, apd, 3.8e-3, 0.5)
    uncapped = rate < apd.cutoff_hz / 0.5
    assert uncapped[:10].all() and not uncapped[-1]  # the front end's bandwidth caps the strong signals
    ber = bit_error_rate(q_factor(power[uncapped], 8e-6, apd, 0.5 * rate[uncapped]))
    assert torch.allclose(ber, torch.full_like(ber, 3.8e-3), rtol=1e-9)
    assert (rate[uncapped].diff() > 0).all() and (rate.diff() >= 0).all()
    assert (rate[~uncapped] == apd.cutoff_hz / 0.5).all()
    assert max_bit_rate(watts(0.0), 8e-6, apd).item() == 0.0


def test_outage_is_a_ber_above_the_fec_limit_and_no_light_is_an_outage():
    link = link_performance(torch.logspace(-9, -1, 200, dtype=F64), LinkBudget())
    assert torch.equal(link.outage, link.ber > 3.8e-3) and link.outage.any() and not link.outage.all()
    assert torch.equal(outage(link.q, 3.8e-3), link.outage)
    dark = link_performance(watts(0.0), LinkBudget())
    assert (dark.received_power.item(), dark.snr.item(), dark.ber.item()) == (0.0, 0.0, 0.5)
    assert dark.outage.item() and dark.max_bit_rate.item() == 0.0


@pytest.mark.parametrize(
    "receiver,background,watts_at_limit",
    [("apd", "day", 31.6e-9), ("apd", "night", 9.1e-9), ("pin", "day", 0.36e-6), ("pin", "night", 0.36e-6)],
)
def test_the_fec_power_has_the_fec_limits_q_and_the_docs_numbers(receiver, background, watts_at_limit):
    link = LinkBudget(receiver=RECEIVERS[receiver], background_radiance=BACKGROUND_RADIANCE[background])
    power = fec_power(link)
    assert power == pytest.approx(watts_at_limit, rel=0.01)  # docs/model.md §9, after the worked example
    q = q_factor(torch.tensor(power, dtype=F64), link.background_power, link.receiver, link.bandwidth)
    assert q.item() == pytest.approx(q_at_ber(3.8e-3), rel=1e-12)


def test_float32_and_float64_agree_and_every_field_keeps_the_gains_shape():
    gain = torch.logspace(-7, -1, 12, dtype=F64).reshape(4, 3)
    wide = link_performance(gain, LinkBudget())
    narrow = link_performance(gain.float(), LinkBudget())
    for name in ("received_power", "snr", "q", "max_bit_rate"):
        assert getattr(wide, name).shape == (4, 3) and getattr(narrow, name).dtype == torch.float32
        assert torch.allclose(getattr(narrow, name).double(), getattr(wide, name), rtol=1e-5)
    assert torch.allclose(narrow.ber.double(), wide.ber, rtol=1e-4, atol=1e-30)
    assert torch.equal(narrow.outage, wide.outage) and narrow.batch_size == (4, 3)


BAD = [
    ("power_w", -1.0, "link.power_w = -1.0 is out of range; allowed (0, 1000] W"),
    ("k_a", 1.5, "link.k_a = 1.5 is out of range; allowed [0, 1]"),
    ("k_a", -0.1, "link.k_a = -0.1 is out of range"),
    ("bit_rate", 0.0, "link.bit_rate = 0.0 is out of range; allowed (0, 8e+07] bit/s"),
    ("bit_rate", 1e9, "link.bit_rate = 1000000000.0 is out of range; allowed (0, 8e+07]"),
    ("cutoff_hz", 0.0, "link.cutoff_hz = 0.0 is out of range; allowed (0, 1e+12] Hz"),
    ("bandwidth_per_rate", 0.0, "link.bandwidth_per_rate = 0.0 is out of range"),
    ("fec_limit", 0.5, "link.fec_limit = 0.5 is out of range; allowed (0, 0.5)"),
    ("gain", 0.5, "link.gain = 0.5 is out of range; allowed [1, 10000]"),
    ("responsivity", 0.0, "link.responsivity = 0.0 is out of range"),
    ("dark_current", -1e-9, "link.dark_current = -1e-09 is out of range"),
    ("temperature", 0.0, "link.temperature = 0.0 is out of range; allowed (0, 10000] K"),
    ("load_resistance", 0.0, "link.load_resistance = 0.0 is out of range"),
    ("filter_bandwidth_nm", 0.0, "link.filter_bandwidth_nm = 0.0 is out of range"),
    ("filter_transmittance", 1.2, "link.filter_transmittance = 1.2 is out of range; allowed (0, 1]"),
    ("background_radiance", -1.0, "link.background_radiance = -1.0 is out of range"),
    ("power_w", "lots", "link.power_w = 'lots' is not a number"),
    ("aperture", 0.05, "link.aperture is not a known key"),
]


LINK_KEYS = ("power_w", "bit_rate", "bandwidth_per_rate", "fec_limit", "filter_bandwidth_nm", "filter_transmittance")
DEFAULT_LINK = {
    **dataclasses.asdict(Receiver()),
    **{key: getattr(LinkBudget(), key) for key in (*LINK_KEYS, "background_radiance")},
}
"""The flat ``link`` keys at their defaults, as the config group holds them."""


@pytest.mark.parametrize("key,value,message", BAD, ids=[f"{k}={v}" for k, v, _ in BAD])
def test_a_bad_link_value_is_a_one_line_error_naming_the_key(key, value, message):
    with pytest.raises(ValueError) as error:
        LinkBudget.from_mapping({**DEFAULT_LINK, key: value})
    assert str(error.value).startswith(message) and "\n" not in str(error.value)


def test_the_presets_are_the_modules_constants_and_the_default_is_the_apd_by_day():
    for name, receiver in RECEIVERS.items():
        keys = OmegaConf.to_container(OmegaConf.load(ROOT / "conf" / "link" / "receiver" / f"{name}.yaml"))
        assert Receiver(**keys) == receiver
    for name, radiance in BACKGROUND_RADIANCE.items():
        preset = OmegaConf.load(ROOT / "conf" / "link" / "background" / f"{name}.yaml")
        assert preset.background_radiance == radiance
    for config in ("config", "evaluate"):
        link = OmegaConf.to_container(compose_config(config).link)
        assert link == DEFAULT_LINK and LinkBudget.from_mapping(link) == LinkBudget()
    night_pin = compose_config("config", ["link/receiver=pin", "link/background=night", "link.power_w=0.5"]).link
    budget = LinkBudget.from_mapping(OmegaConf.to_container(night_pin))
    assert (budget.receiver, budget.background_radiance, budget.power_w) == (RECEIVERS["pin"], 1.25e-8, 0.5)


def test_background_power_is_radiance_times_band_transmittance_and_etendue():
    # 1 W/(m² sr nm) over 1 nm, a perfect filter, a 1 m² aperture and a hemisphere of view: 2π W.
    diameter = math.sqrt(4.0 / math.pi)
    assert background_power(1.0, 1.0, 1.0, diameter, math.pi / 2) == pytest.approx(2.0 * math.pi, rel=1e-12)


def test_the_received_power_of_links_with_their_own_divergence_is_each_ones_budget():
    """P_r per link through each link's beam (J_0/P_t = 2/(π ω_D′²)) equals the budget at that divergence, bit
    for bit in float32 and float64, and the snr reward follows it: a narrower beam puts more power on the
    receiver for the same gain."""
    divergences = torch.tensor([0.005, 0.02, 0.1], dtype=torch.float64)
    budget = LinkBudget()
    for dtype in (torch.float32, torch.float64):
        gain = torch.tensor([[2e-3, 1e-4], [3e-3, 0.0], [5e-4, 1e-2]], dtype=dtype)
        per_link = received_power(gain, budget, divergences)
        assert per_link.dtype == dtype
        for row, value in enumerate(divergences.tolist()):
            alone = replace(budget, optics=Transceiver(divergence=value))
            assert torch.equal(per_link[row], received_power(gain[row], alone))
    reward = Reward(name="snr", link=budget)
    gain = torch.full((3,), 1e-3)
    rewarded = reward(gain, gain=gain, divergence=divergences)
    assert rewarded[0] > rewarded[1] > rewarded[2]
    assert (
        rewarded[2] == Reward(name="snr", link=replace(budget, optics=Transceiver(divergence=0.1)))(gain, gain=gain)[2]
    )
