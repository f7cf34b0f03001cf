"""From scene luminance to 8-bit pixels, physically (DESIGN §4).

Luminance L (cd/m²) of a Lambertian surface of albedo ρ under illuminance E (lx) is
``L = ρ E / π``. The camera equation gives the image-plane illuminance
``E_img = π L τ / (4 N²)`` (f-number N, lens transmission τ; the cos⁴ fall-off is applied as a
vignetting map by the renderer). Photons follow from ~4.1e15 photons/(s·m²) per lux near
555 nm, times the pixel area and the quantum efficiency, times the exposure time. Then Poisson
shot noise, the full well, read noise, analogue gain, gamma and 8-bit quantisation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F_NUMBER = 2.0
LENS_TRANSMISSION = 0.9
PIXEL_PITCH_M = 4.65e-6  # Sony ICX204 (Bumblebee2)
QUANTUM_EFFICIENCY = 0.5
PHOTONS_PER_LUX_S_M2 = 4.1e15  # at 555 nm, 683 lm/W
FULL_WELL_E = 20_000.0
READ_NOISE_E = 12.0
PRNU = 0.01  # pixel response non-uniformity, relative std
EXPOSURE_MAX_S = 1.0 / 15.0
EXPOSURE_MIN_S = 1e-5
GAIN_MAX = 16.0
GAMMA = 2.2
AE_TARGET = 0.18  # auto-exposure puts the median pixel at 18 % of white (DN ≈ 117 after gamma)
FIXED_EXPOSURE_LUX = 500.0  # "fixed" mode freezes what auto chose at this level

#: Photo-electrons per second per pixel for a luminance of 1 cd/m², on the optical axis.
ELECTRONS_PER_NIT_S = (np.pi * LENS_TRANSMISSION / (4.0 * F_NUMBER**2)
                       * PHOTONS_PER_LUX_S_M2 * PIXEL_PITCH_M**2 * QUANTUM_EFFICIENCY)


@dataclass(frozen=True)
class Exposure:
    """Exposure time (s) and analogue gain (× , ≥ 1) of one frame."""

    time_s: float
    gain: float


def auto_exposure(median_luminance: float) -> Exposure:
    """Put a scene whose median pixel sees ``median_luminance`` (cd/m²) at ``AE_TARGET`` of
    white: lengthen the exposure up to 1/15 s first, then raise the gain up to 16×; beyond
    that the image is simply dim."""
    rate = max(float(median_luminance) * ELECTRONS_PER_NIT_S, 1e-9)  # e-/s
    target_e = AE_TARGET * FULL_WELL_E
    t = float(np.clip(target_e / rate, EXPOSURE_MIN_S, EXPOSURE_MAX_S))
    gain = float(np.clip(target_e / (rate * t), 1.0, GAIN_MAX))
    return Exposure(time_s=t, gain=gain)


def choose_exposure(median_luminance: float, lux: float, mode: str) -> Exposure:
    """Auto-exposure for this frame, or (``mode="fixed"``) what auto would choose for the same
    scene at ``FIXED_EXPOSURE_LUX`` — luminance is proportional to illuminance."""
    if mode == "auto":
        return auto_exposure(median_luminance)
    if mode == "fixed":
        return auto_exposure(median_luminance * FIXED_EXPOSURE_LUX / lux)
    raise ValueError(f"exposure: expected 'auto' or 'fixed', got {mode!r}")


def expose(luminance: NDArray[np.float32], exposure: Exposure, rng: np.random.Generator, *,
           prnu: NDArray[np.float32] | None = None) -> NDArray[np.uint8]:
    """Turn a luminance image into an 8-bit frame.

    Parameters
    ----------
    luminance : ndarray, shape (H, W), float32
        Scene luminance seen by each pixel (vignetting included), cd/m².
    exposure : Exposure
    rng : Generator
        Noise.
    prnu : ndarray, shape (H, W), float32, optional
        Fixed per-pixel gain pattern (≈ 1).

    Returns
    -------
    ndarray, shape (H, W), uint8
        Gamma-encoded (1/2.2) grey levels.
    """
    electrons = luminance * np.float32(ELECTRONS_PER_NIT_S * exposure.time_s)
    if prnu is not None:
        electrons *= prnu
    # Shot noise: Poisson where few electrons, its Gaussian limit elsewhere (same mean and
    # variance, 5x faster on a megapixel).
    noisy = electrons + np.sqrt(electrons) * rng.standard_normal(electrons.shape, dtype=np.float32)
    low = electrons < 30.0
    if np.any(low):
        noisy[low] = rng.poisson(electrons[low]).astype(np.float32)
    np.clip(noisy, 0.0, FULL_WELL_E, out=noisy)
    noisy += np.float32(READ_NOISE_E) * rng.standard_normal(noisy.shape, dtype=np.float32)
    linear = noisy * np.float32(exposure.gain / FULL_WELL_E)
    np.clip(linear, 0.0, 1.0, out=linear)
    return gamma_encode(linear)


_GAMMA_LUT_SIZE = 4096
_GAMMA_LUT = (255.0 * np.linspace(0.0, 1.0, _GAMMA_LUT_SIZE) ** (1.0 / GAMMA) + 0.5).astype(np.uint8)


def gamma_encode(linear: NDArray[np.float32]) -> NDArray[np.uint8]:
    """Linear [0, 1] → gamma 1/2.2 → uint8 (a 12-bit ADC then a look-up table, as cameras do)."""
    idx = (linear * np.float32(_GAMMA_LUT_SIZE - 1) + np.float32(0.5)).astype(np.int32)
    return _GAMMA_LUT[idx]
