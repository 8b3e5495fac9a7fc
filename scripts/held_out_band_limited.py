#!/usr/bin/env python3
"""Held-out SNR of recovered WAVs against a reference band-limited to each
WAV's own Nyquist frequency.

`vibroscope calibrate` (and the test suite's held-out scorer) sample the
reference at the recovery's sample instants, so its target holds the
reference's aliases; a recovery at the frame rate that folds the sound as
the camera does scores well against it, one that removes the aliases or
unfolds them (`listen --calibration --unfold`) does not. This scorer uses
the same model (delay and gain on the fit blocks, 0.1 s blocks 0, 2, 4 of
every five; SNR on blocks 1 and 3; the default 4th-order high-pass of the
WAV's rate, fs/40 within 20-100 Hz, on the target), with the reference
resampled to the WAV's rate (scipy's resample_poly, anti-aliased).

usage: held_out_band_limited.py REFERENCE.wav RECOVERY.wav [RECOVERY.wav ...]
"""
import sys

import numpy as np
import scipy.io.wavfile as wavfile
import scipy.signal as ss


def read(path):
    rate, x = wavfile.read(path)
    if x.ndim > 1:
        x = x[:, 0]
    return rate, x.astype(float)


def cutoff(fs):
    return min(max(fs / 40.0, 20.0), 100.0, fs / 4.0)


def score(reference, rate_ref, path):
    fs, z = read(path)
    n = len(z)
    base = ss.resample_poly(reference, int(fs), int(rate_ref))
    base = np.concatenate([base, np.zeros(max(0, n + 2000 - len(base)))])[: n + 2000]
    sos = ss.butter(4, cutoff(fs), "high", fs=fs, output="sos")
    block = int(2 ** round(np.log2(0.1 * fs)))
    fit = np.array([(i // block) % 5 not in (1, 3) for i in range(n)])
    freqs = np.fft.rfftfreq(len(base), 1.0 / fs)
    spectrum = np.fft.rfft(base)

    def target(tau):
        t = np.fft.irfft(spectrum * np.exp(-2j * np.pi * freqs * tau), len(base))[:n]
        return ss.sosfilt(sos, t)

    def sse(tau):
        t = target(tau)
        g = np.dot(t[fit], z[fit]) / np.dot(t[fit], t[fit])
        return np.sum((z[fit] - g * t[fit]) ** 2), g, t

    lag = min(range(-200, 200), key=lambda k: sse(k / fs)[0])
    tau = min(np.linspace((lag - 1) / fs, (lag + 1) / fs, 81), key=lambda t: sse(t)[0])
    _, g, t = sse(tau)
    held = ~fit
    return fs, 10 * np.log10(np.sum(t[held] ** 2) / np.sum((z[held] / g - t[held]) ** 2))


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    rate_ref, reference = read(sys.argv[1])
    for path in sys.argv[2:]:
        fs, snr = score(reference, rate_ref, path)
        print(f"{path}: {fs} Hz, held-out SNR {snr:.2f} dB against the reference band-limited to {fs / 2:.0f} Hz")


if __name__ == "__main__":
    main()
