"""The link budget: from the channel gain G to received power, noise, SNR, BER, rate and outage.

docs/model.md §9, equations (9.1)-(9.13). SI units throughout (watts, amperes, hertz, bit/s,
metres, radians); the optical filter's bandwidth is in nanometres, as datasheets give it, and the
background radiance in W/(m² sr nm) to match. Every function is elementwise over tensors of any
shape, in their dtype and on their device; the dataclasses hold plain floats.

    P_r = T_f · P_t · (J_0/P_t) · G · A_det          signal power on the detector      (9.4)
    σ²  = 2q(ℜP + ℜP_b + I_d)M²F(M)B + 4k_B T B/R_L   noise of a level of power P       (9.8)
    Q   = (I_1 − I_0)/(σ_1 + σ_0),  BER = ½ erfc(Q/√2)  OOK NRZ, levels 0 and 2P_r     (9.9), (9.10)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from statistics import NormalDist

import torch
from tensordict import TensorClass

from waterair.core.validation import check_range
from waterair.physics.channel import Transceiver
from waterair.physics.optics import Scalar, beam_divergence, per_link

ELEMENTARY_CHARGE = 1.602176634e-19
"""q (C), exact in the SI since 2019."""
BOLTZMANN = 1.380649e-23
"""k_B (J/K), exact in the SI since 2019."""
FEC_LIMIT = 3.8e-3
"""Pre-FEC BER that a 7 % overhead hard-decision FEC corrects (ITU-T G.975.1, App. I.9), docs/model.md §9."""


def _checked(owner, name: str, low: float, high: float, **kwargs) -> None:
    """Validate ``owner.name`` (one-line error naming it) and store it as a float."""
    object.__setattr__(owner, name, check_range(name, getattr(owner, name), low, high, **kwargs))


@dataclass(frozen=True)
class Receiver:
    """Photodiode and front end (docs/model.md §9, presets in :data:`RECEIVERS`); defaults: the APD preset.

    Attributes:
        responsivity: ℜ at unit gain (A/W), in (0, 10].
        gain: avalanche gain M, in [1, 1e4] (1: a PIN photodiode).
        k_a: ionisation ratio k_A of McIntyre's excess noise, in [0, 1].
        dark_current: primary (unmultiplied) dark current I_d (A), in [0, 1e-3]: a datasheet's
            dark current at gain M, divided by M.
        temperature: noise temperature of the load T (K), in (0, 1e4].
        load_resistance: load or transimpedance R_L (Ω), in (0, 1e12].
        cutoff_hz: the front end's −3 dB bandwidth (Hz), in (0, 1e12]: the largest electrical
            bandwidth B the receiver has.
    """

    responsivity: float = 0.3
    gain: float = 40.0
    k_a: float = 0.027
    dark_current: float = 7.5e-11
    temperature: float = 300.0
    load_resistance: float = 50.0
    cutoff_hz: float = 4.0e7

    def __post_init__(self) -> None:
        _checked(self, "responsivity", 0.0, 10.0, low_open=True, unit="A/W")
        _checked(self, "gain", 1.0, 1.0e4)
        _checked(self, "k_a", 0.0, 1.0)
        _checked(self, "dark_current", 0.0, 1.0e-3, unit="A")
        _checked(self, "temperature", 0.0, 1.0e4, low_open=True, unit="K")
        _checked(self, "load_resistance", 0.0, 1.0e12, low_open=True, unit="ohm")
        _checked(self, "cutoff_hz", 0.0, 1.0e12, low_open=True, unit="Hz")


RECEIVERS = {
    "apd": Receiver(),
    "pin": Receiver(gain=1.0, dark_current=1.0e-9, cutoff_hz=3.5e7),  # k_a is not read: F(1) = 1
}
"""Receiver presets (conf/link/receiver/), their sources in docs/model.md §9."""
BACKGROUND_RADIANCE = {"day": 5.0e-3, "night": 1.25e-8}
"""Radiance of the sea seen from above, W/(m² sr nm) at 520 nm (conf/link/background/, docs/model.md §9)."""


@dataclass(frozen=True)
class LinkBudget:
    """Everything between the channel gain and the bit error rate (docs/model.md §9).

    Attributes:
        power_w: transmitted optical power P_t (W), in (0, 1e3].
        bit_rate: OOK NRZ bit rate R_b (bit/s), in (0, cutoff_hz / bandwidth_per_rate].
        bandwidth_per_rate: B / R_b, the electrical (noise) bandwidth per bit rate, in (0, 10].
        fec_limit: the largest BER the FEC corrects, in (0, 0.5).
        filter_bandwidth_nm: optical filter bandwidth Δλ (nm), in (0, 1e3].
        filter_transmittance: optical filter transmittance T_f, in (0, 1].
        background_radiance: radiance L_b the receiver sees (W/(m² sr nm)), in [0, 1e4].
        receiver: the photodiode and front end.
        optics: the channel's transceiver (wavelength λ, divergence ω_D, half FOV ω_A, n_c and the
            receiver's aperture diameter D, validated there).
    """

    power_w: float = 0.05
    bit_rate: float = 1.0e7
    bandwidth_per_rate: float = 0.5
    fec_limit: float = FEC_LIMIT
    filter_bandwidth_nm: float = 10.0
    filter_transmittance: float = 0.9
    background_radiance: float = BACKGROUND_RADIANCE["day"]
    receiver: Receiver = field(default_factory=Receiver)
    optics: Transceiver = field(default_factory=Transceiver)

    def __post_init__(self) -> None:
        _checked(self, "power_w", 0.0, 1.0e3, low_open=True, unit="W")
        _checked(self, "bandwidth_per_rate", 0.0, 10.0, low_open=True)
        top = self.receiver.cutoff_hz / self.bandwidth_per_rate
        _checked(self, "bit_rate", 0.0, top, low_open=True, unit="bit/s (cutoff_hz / bandwidth_per_rate)")
        _checked(self, "fec_limit", 0.0, 0.5, low_open=True, high_open=True)
        _checked(self, "filter_bandwidth_nm", 0.0, 1.0e3, low_open=True, unit="nm")
        _checked(self, "filter_transmittance", 0.0, 1.0, low_open=True)
        _checked(self, "background_radiance", 0.0, 1.0e4, unit="W/(m² sr nm)")

    @classmethod
    def from_mapping(cls, values: Mapping, optics: Transceiver | None = None) -> LinkBudget:
        """Build from the flat ``link`` config group; every error names ``link.<key>``, unknown keys too.

        The optics, the aperture among them, are the channel's (the ``env`` group's), never the link's own.
        """
        receiver_keys = {f.name for f in dataclasses.fields(Receiver)}
        own_keys = {f.name for f in dataclasses.fields(cls)} - {"receiver", "optics"}
        unknown = sorted(set(values) - receiver_keys - own_keys)
        if unknown:
            allowed = ", ".join(sorted(receiver_keys | own_keys))
            raise ValueError(f"link.{unknown[0]} is not a known key; allowed: {allowed}")
        try:
            receiver = Receiver(**{k: v for k, v in values.items() if k in receiver_keys})
            own = {k: v for k, v in values.items() if k in own_keys}
            return cls(**own, receiver=receiver, optics=optics or Transceiver())
        except ValueError as error:
            raise ValueError(f"link.{error}") from None

    @property
    def bandwidth(self) -> float:
        """Electrical bandwidth B = bandwidth_per_rate · R_b (Hz) at the operating bit rate (eq. 9.11)."""
        return self.bandwidth_per_rate * self.bit_rate

    @property
    def detector_area(self) -> float:
        """A_det (m²), eq. (9.3)."""
        return detector_area(self.optics.aperture_diameter, self.optics.half_fov, self.optics.concentrator_index)

    @property
    def received_power_per_gain(self) -> float:
        """P_r / G = T_f P_t (J_0/P_t) A_det (W m²), eq. (9.4): multiply by G for P_r."""
        return float(self.power_per_gain(self.optics.divergence))

    def power_per_gain(self, divergence: Scalar) -> Scalar:
        """P_r / G (W m²), eq. (9.4), for a beam of divergence ω_D (rad): a float, or one per link ``[B]``
        (float64; J_0/P_t = 2/(π ω_D′²) is the beam's, the rest the budget's)."""
        intensity = on_axis_intensity_per_watt(divergence, self.optics.wavelength)
        return self.filter_transmittance * self.power_w * intensity * self.detector_area

    @property
    def background_power(self) -> float:
        """P_b (W) on the detector, eq. (9.6)."""
        return background_power(
            self.background_radiance,
            self.filter_bandwidth_nm,
            self.filter_transmittance,
            self.optics.aperture_diameter,
            self.optics.half_fov,
        )


class LinkPerformance(TensorClass):
    """What the link delivers for each gain (every field shaped like the gain; docs/model.md §9).

    ``received_power`` P_r (W); ``snr`` the electrical SNR (eq. 9.12, linear); ``q`` the Q factor;
    ``ber`` the bit error rate at the operating bit rate; ``outage`` BER above the FEC limit;
    ``max_bit_rate`` the largest bit rate with BER at most the FEC limit (bit/s).
    """

    received_power: torch.Tensor
    snr: torch.Tensor
    q: torch.Tensor
    ber: torch.Tensor
    outage: torch.Tensor
    max_bit_rate: torch.Tensor


def link_performance(gain: torch.Tensor, budget: LinkBudget) -> LinkPerformance:
    """P_r, SNR, Q, BER, outage and the largest bit rate for channel gains ``gain`` (1/m², any shape).

    The one call the environment and the evaluation make (docs/model.md §9); a gain of 0 (no
    path) gives P_r = 0, SNR 0, BER ½, outage and a rate of 0.
    """
    power = received_power(gain, budget)
    noise = (budget.background_power, budget.receiver)
    q = q_factor(power, *noise, budget.bandwidth)
    return LinkPerformance(
        received_power=power,
        snr=snr(power, *noise, budget.bandwidth),
        q=q,
        ber=bit_error_rate(q),
        outage=outage(q, budget.fec_limit),
        max_bit_rate=max_bit_rate(power, *noise, budget.fec_limit, budget.bandwidth_per_rate),
        batch_size=gain.shape,
    )


def on_axis_intensity_per_watt(divergence: Scalar, wavelength: float) -> Scalar:
    """J_0 / P_t = 2 / (π ω_D'²) (1/sr): the Gaussian beam's radiant intensity on its axis per watt, eq. (9.2).

    G_D (docs/model.md §4) is the beam's angular profile normalised to 1 on its axis; this is the
    factor that makes it a radiant intensity. Args as :func:`beam_divergence`.
    """
    return 2.0 / (math.pi * beam_divergence(divergence, wavelength) ** 2)


def detector_area(aperture_diameter: float, half_fov: float, concentrator_index: float = 1.0) -> float:
    """A_det = (π D²/4) sin²ω_A / n_c² (m²): the detector area an ideal concentrator fills, eq. (9.3).

    Args:
        aperture_diameter: receiver aperture diameter D (m).
        half_fov: half field of view ω_A (rad).
        concentrator_index: concentrator refractive index n_c.

    G_A = (n_c²/sin²ω_A) cos α_A carries the concentrator's gain, so G · A_det is the aperture's
    projected area times the irradiance per unit radiant intensity (étendue conservation).
    """
    return aperture_area(aperture_diameter) * math.sin(half_fov) ** 2 / concentrator_index**2


def received_power(gain: torch.Tensor, budget: LinkBudget, divergence: torch.Tensor | None = None) -> torch.Tensor:
    """P_r = T_f · P_t · (J_0/P_t) · G · A_det (W) on the detector, eq. (9.4).

    Args:
        gain: channel gain G (1/m²), any shape (docs/model.md §4); ``[B, ...]`` with ``divergence``.
        budget: the link budget (its transmitter power, optics, aperture and filter).
        divergence: each link's beam divergence ω_D (rad) ``[B]``, where links have their own; None: the
            budget's optics'.
    """
    if divergence is None:
        return gain * budget.received_power_per_gain
    return gain * per_link(budget.power_per_gain(divergence.double()), gain)


def aperture_area(aperture_diameter: float) -> float:
    """A = π D²/4 (m²) of an aperture of diameter D (m)."""
    return math.pi * aperture_diameter**2 / 4.0


def fov_solid_angle(half_fov: float) -> float:
    """Ω_FOV = 2π (1 − cos ω_A) (sr): the field of view's solid angle, eq. (9.5). ω_A in rad."""
    return 2.0 * math.pi * (1.0 - math.cos(half_fov))


def background_power(
    radiance: float, filter_bandwidth_nm: float, filter_transmittance: float, aperture_diameter: float, half_fov: float
) -> float:
    """P_b = L_b Δλ T_f A Ω_FOV (W): background light on the detector, eq. (9.6).

    Args:
        radiance: background radiance L_b (W/(m² sr nm)).
        filter_bandwidth_nm: optical filter bandwidth Δλ (nm).
        filter_transmittance: filter transmittance T_f.
        aperture_diameter: aperture diameter D (m).
        half_fov: half field of view ω_A (rad).
    """
    etendue = aperture_area(aperture_diameter) * fov_solid_angle(half_fov)
    return radiance * filter_bandwidth_nm * filter_transmittance * etendue


def excess_noise_factor(gain: float, k_a: float) -> float:
    """McIntyre's excess noise factor F(M) = k_A M + (1 − k_A)(2 − 1/M), eq. (9.7); F(1) = 1.

    Args:
        gain: avalanche gain M ≥ 1.
        k_a: ionisation ratio k_A in [0, 1].
    """
    return k_a * gain + (1.0 - k_a) * (2.0 - 1.0 / gain)


def noise_variance(
    power: torch.Tensor, background_power: float, receiver: Receiver, bandwidth: float | torch.Tensor
) -> torch.Tensor:
    """σ² = 2q(ℜP + ℜP_b + I_d) M² F(M) B + 4 k_B T B / R_L (A²): shot plus thermal noise, eq. (9.8).

    Args:
        power: signal power P on the detector during the level (W), any shape.
        background_power: background power P_b on the detector (W).
        receiver: the photodiode and front end.
        bandwidth: electrical bandwidth B (Hz), a float or a tensor broadcastable with ``power``.
    """
    r = receiver
    primary = r.responsivity * (power + background_power) + r.dark_current
    shot = 2.0 * ELEMENTARY_CHARGE * primary * r.gain**2 * excess_noise_factor(r.gain, r.k_a)
    thermal = 4.0 * BOLTZMANN * r.temperature / r.load_resistance
    return (shot + thermal) * bandwidth


def q_factor(
    received_power: torch.Tensor, background_power: float, receiver: Receiver, bandwidth: float | torch.Tensor
) -> torch.Tensor:
    """Q = (I_1 − I_0)/(σ_1 + σ_0) of OOK NRZ with levels 0 and 2 P_r, eq. (9.9).

    Args:
        received_power: average signal power P_r on the detector (W), any shape.
        background_power, receiver, bandwidth: as :func:`noise_variance`.

    The threshold between the levels is the optimal one of the Gaussian approximation.
    """
    one = 2.0 * received_power
    signal = receiver.responsivity * receiver.gain * one
    sigma_1 = noise_variance(one, background_power, receiver, bandwidth).sqrt()
    sigma_0 = noise_variance(torch.zeros_like(one), background_power, receiver, bandwidth).sqrt()
    return signal / (sigma_1 + sigma_0)


def bit_error_rate(q: torch.Tensor) -> torch.Tensor:
    """BER = ½ erfc(Q/√2), eq. (9.10): Q = 6 gives 9.87e-10; Q = 0 gives ½."""
    return 0.5 * torch.special.erfc(q / math.sqrt(2.0))


def q_at_ber(ber: float) -> float:
    """The Q factor whose BER (eq. 9.10) is ``ber`` in (0, ½): Q = −Φ⁻¹(BER); 3.8e-3 gives 2.669."""
    return -NormalDist().inv_cdf(ber)


def fec_power(budget: LinkBudget) -> float:
    """The received power P_r (W) at which BER = the FEC limit at the operating bit rate, eq. (9.14).

    σ(2P)² = σ(0)² + 2kP with k = 2qℜM²F B, and Q = aP/(σ(2P) + σ(0)) with a = 2Mℜ, so Q = Q_FEC at
    P = 2 Q_FEC (k Q_FEC + a σ(0)) / a². Below it the link is in outage (eq. 9.13).
    """
    r, q_fec = budget.receiver, q_at_ber(budget.fec_limit)
    a = 2.0 * r.gain * r.responsivity
    k = 2.0 * ELEMENTARY_CHARGE * r.responsivity * r.gain**2 * excess_noise_factor(r.gain, r.k_a) * budget.bandwidth
    zero = torch.zeros((), dtype=torch.float64)
    sigma_0 = noise_variance(zero, budget.background_power, r, budget.bandwidth).sqrt().item()
    return 2.0 * q_fec * (k * q_fec + a * sigma_0) / a**2


def outage(q: torch.Tensor, fec_limit: float = FEC_LIMIT) -> torch.Tensor:
    """Outage: BER above the FEC limit, i.e. Q below Q(fec_limit), eq. (9.13); bool, shaped like ``q``."""
    return q < q_at_ber(fec_limit)


def snr(
    received_power: torch.Tensor, background_power: float, receiver: Receiver, bandwidth: float | torch.Tensor
) -> torch.Tensor:
    """Electrical SNR = (M ℜ P_r)² / σ²(P_r) at the average received power (linear), eq. (9.12).

    The textbook SNR of a photoreceiver; the BER follows from Q (eq. 9.9), not from it. Where the
    thermal noise dominates, SNR = Q²; where the signal's shot noise does, SNR = Q²/2.
    Args as :func:`q_factor`.
    """
    signal = receiver.gain * receiver.responsivity * received_power
    return signal**2 / noise_variance(received_power, background_power, receiver, bandwidth)


def max_bit_rate(
    received_power: torch.Tensor,
    background_power: float,
    receiver: Receiver,
    fec_limit: float = FEC_LIMIT,
    bandwidth_per_rate: float = 0.5,
) -> torch.Tensor:
    """The largest bit rate with BER ≤ ``fec_limit`` (bit/s), at most cutoff_hz / bandwidth_per_rate, eq. (9.11).

    Every noise term grows as B, so Q = I_s / (√B (s_1 + s_0)) with s_i the noise densities
    (A/√Hz): Q = Q(fec_limit) is solved in closed form, B* = (I_s / (Q_FEC (s_1 + s_0)))², and
    R* = B* / bandwidth_per_rate. Increasing in P_r; 0 where P_r = 0.
    Args as :func:`q_factor`; ``bandwidth_per_rate`` is B / R_b.
    """
    one = 2.0 * received_power
    signal = receiver.responsivity * receiver.gain * one
    s_1 = noise_variance(one, background_power, receiver, 1.0).sqrt()
    s_0 = noise_variance(torch.zeros_like(one), background_power, receiver, 1.0).sqrt()
    bandwidth = (signal / (q_at_ber(fec_limit) * (s_1 + s_0))) ** 2
    return torch.clamp(bandwidth, max=receiver.cutoff_hz) / bandwidth_per_rate
