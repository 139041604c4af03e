"""Features computed from backlash-test records (paper section 3: wavelet coefficients)."""

from engine.features.wavelet import Band, channel_features, level_slices, wavelet_coefficients, wavelet_reconstruct

__all__ = ["Band", "channel_features", "level_slices", "wavelet_coefficients", "wavelet_reconstruct"]
