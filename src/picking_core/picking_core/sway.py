"""Where a swaying apple will be (pure core): a motion model fitted to a camera's stamped detections.

An apple hangs from its stem as a damped pendulum; a steady wind drives it at the wind's frequency (a gust
rings it at its own for a second or two, then the ringing dies away). So the model is a sway about where the
apple hangs: along each axis ``c + a sin(w t) + b cos(w t)``, one frequency ``w`` for the three axes (the apple
moves along one arc), fitted to the detections of the last ``window`` s by weighted least squares. For a
given ``w`` the fit is linear (the offsets and amplitudes solve at once); ``w`` is found by a search over
``frequencies`` and refined where the residual is least. When a sway explains no more than the detections'
noise, the apple is still: the model is its mean.

A fit over a window of a few periods finds the frequency itself (why not a Kalman filter: docs/decisions.md),
and its residual says how far the apple strays from a steady sway (a gust): the prediction's covariance grows with
it, which is what tells a picker to wait.

Each detection is placed at its own stamp (the capture time): the camera's latency is then a longer
prediction, not a bias. A detection stamped before the newest one applied is refused (out of order), as is one
that is not finite; one stamped ahead of the clock is the caller's to refuse (it knows the clock).
"""

from __future__ import annotations

import collections
from dataclasses import dataclass, replace

import numpy as np

#: s: a detection stamped this much before the newest one applied is out of order (refused).
OUT_OF_ORDER = 1e-6
#: m: how far apart one apple's places in consecutive frames may lie for noise alone (a camera's 3 mm, four
#: deviations of the difference), and m/s: the fastest it sways (40 mm at 2 Hz).
TRACK_GATE, TRACK_SPEED = 0.017, 0.5


@dataclass(frozen=True)
class SwaySettings:
    """``window`` s of detections fitted; ``frequencies`` ``(lowest, highest, step)`` Hz searched; ``min_span`` s
    of detections before a sway is fitted (less: still); ``significance``: how much a sway must lower the fit's
    chi-square (the squared residuals in units of the noise) to be believed (a sway of amplitude A seen N times
    through noise s lowers it by about N A^2 / 2 s^2: 4 mm seen 60 times through 3 mm, by 53); ``max_gap`` s
    without a detection after which the fit starts over; ``recent`` s of residuals that say whether the apple
    still sways as fitted (a gust begun)."""

    window: float = 2.0
    frequencies: tuple = (0.4, 3.0, 0.02)
    min_span: float = 0.8
    significance: float = 40.0
    max_gap: float = 1.0
    recent: float = 0.5


@dataclass(frozen=True)
class Fit:
    """The motion fitted, along each axis: ``coeffs`` (3, 5) m of 1, sin, cos, and the second harmonic's sin and
    cos (a pendulum rises and falls twice a swing) at ``frequency`` Hz (0: still: the centre alone), time counted
    from ``t0`` s; ``cov`` (3, 5, 5) their covariance; ``rms`` (3,) m how far the apple strays from the model
    beyond the detections' noise; ``span`` s of detections; ``frequency_sd`` Hz, the frequency's standard deviation."""

    coeffs: np.ndarray
    cov: np.ndarray
    frequency: float
    t0: float
    rms: np.ndarray
    span: float
    frequency_sd: float = 0.0

    @property
    def centre(self):
        """(3,) m: where the apple hangs, the centre of its sway."""
        return self.coeffs[:, 0]

    @property
    def amplitude(self):
        """m: the sway's half-width (its first harmonic) along its direction."""
        return float(np.sqrt(np.sum(self.coeffs[:, 1:3] ** 2)))

    def row(self, t):
        """(5,): the model's terms at ``t`` s."""
        return _design(np.array([t - self.t0]), self.frequency, 5)[0]


def _terms(t, frequencies):
    """(K, N, 5): the sway's terms at times ``t`` (N,) for each of ``frequencies`` (K,) Hz."""
    phase = 2 * np.pi * np.asarray(frequencies, float)[:, None] * np.asarray(t, float)[None]
    return np.stack([np.ones_like(phase), np.sin(phase), np.cos(phase), np.sin(2 * phase), np.cos(2 * phase)], axis=2)


def _design(t, f, terms=None):
    """The model's terms at times ``t`` (N,) for frequency ``f`` Hz: (N, 5), or (N, 1) for a still apple (padded
    with zeros to ``terms`` columns when given)."""
    X = _terms(t, [f])[0] if f > 0 else np.ones((len(t), 1))
    if terms is not None and X.shape[1] < terms:
        X = np.hstack([X, np.zeros((len(X), terms - X.shape[1]))])
    return X


def _weighted_fit(X, z, w):
    """Weighted least squares of ``z`` (N, 3 axes) on the terms ``X`` (K, N, p), weights ``w`` (3, N), for every one
    of the K term sets and axes at once: ``(coefficients (K, 3, p), normal matrices (K, 3, p, p), residuals
    (K, 3, N))``."""
    A = np.einsum('an,kni,knj->kaij', w, X, X)
    b = np.einsum('an,kni,na->kai', w, X, z)
    beta = np.linalg.solve(A, b[..., None])[..., 0]
    return beta, A, z.T[None] - np.einsum('kni,kai->kan', X, beta)


class SwayFit:
    """One apple's motion (see the module): :meth:`update` with each stamped detection, :meth:`predict` where it
    will be at any time, with the prediction's covariance."""

    def __init__(self, settings=SwaySettings()):
        self.s = settings
        self.t = -np.inf                      # the newest detection's stamp
        self.refused = 0
        self._seen = collections.deque()      # (t, z (3,), variances (3,))
        self._fit = None

    def update(self, t, z, R):
        """The detection ``z`` (3,) m with covariance ``R`` (3, 3), stamped ``t`` s; False when refused (not finite,
        or older than the newest one applied)."""
        z, R = np.asarray(z, float).reshape(3), np.asarray(R, float).reshape(3, 3)
        if not (np.isfinite(t) and np.all(np.isfinite(z)) and np.all(np.isfinite(R))) or t < self.t - OUT_OF_ORDER:
            self.refused += 1
            return False
        if t - self.t > self.s.max_gap:
            self._seen.clear()
        self._seen.append((float(t), z, np.maximum(np.diag(R), 1e-12)))
        self.t = max(self.t, float(t))
        while self._seen and self._seen[0][0] < self.t - self.s.window:
            self._seen.popleft()
        self._fit = None
        return True

    @property
    def newest(self):
        """The newest detection applied (3,), m, or None before any."""
        return self._seen[-1][1] if self._seen else None

    def recent(self, since):
        """``(n, spread)``: how many detections are stamped at ``since`` s or later, and the farthest one lies from
        their mean, m (0 with none): how often the apple was seen lately and how far it moved."""
        recent = np.array([z for t, z, _ in self._seen if t >= since]).reshape(-1, 3)
        spread = float(np.max(np.linalg.norm(recent - recent.mean(axis=0), axis=1))) if len(recent) else 0.0
        return len(recent), spread

    def fit(self):
        """The :class:`Fit` of the detections in the window, or None before any."""
        if self._fit is None and self._seen:
            self._fit = self._fitted()
        return self._fit

    def predict(self, t):
        """``(mean (3,), covariance (3, 3))`` of where the apple's centre is at ``t`` s; None before any detection.
        The covariance holds the fit's own uncertainty and its residual (how far the apple strays from a steady
        sway), and grows with how far ``t`` lies beyond the detections."""
        f = self.fit()
        if f is None:
            return None
        row = f.row(t)
        mean = f.coeffs @ row
        var = np.einsum('i,aij,j->a', row, f.cov, row) + f.rms ** 2
        if f.frequency > 0:
            # A frequency off by its deviation turns the phase by this much a second beyond the detections.
            drift = 2 * np.pi * f.frequency_sd * max(0.0, t - self.t)
            var = var + (np.sqrt(np.sum(f.coeffs[:, 1:3] ** 2, axis=1)) * drift) ** 2
        return mean, np.diag(var)

    # -- inside -----------------------------------------------------------------------------------
    @staticmethod
    def _resolution(span):
        """Hz: how finely a window of ``span`` s tells a frequency (a tenth of a cycle over it)."""
        return 0.1 / max(span, 1e-3)

    def _fitted(self):
        t = np.array([x[0] for x in self._seen])
        z = np.array([x[1] for x in self._seen])                       # (N, 3)
        v = np.array([x[2] for x in self._seen])                       # (N, 3)
        t0, span = self.t, float(t[-1] - t[0])
        still = self._solve(t - t0, z, v, 0.0)
        if span < self.s.min_span or len(t) < 8:
            return still
        lo, hi, step = self.s.frequencies
        # A coarse search, then a fine one about its best, then the parabola through the least and its neighbours.
        coarse = np.arange(lo, hi + step, 4 * step)
        around = coarse[int(np.argmin(self._chi2(t - t0, z, v, coarse)))]
        grid = np.arange(max(lo, around - 4 * step), min(hi, around + 4 * step) + step / 2, step)
        chi = self._chi2(t - t0, z, v, grid)
        k = int(np.argmin(chi))
        best, sd = grid[k], self._resolution(span)
        if 0 < k < len(grid) - 1:
            c0, c1, c2 = chi[k - 1], chi[k], chi[k + 1]
            denom = c0 - 2 * c1 + c2
            if denom > 0:
                best = best + 0.5 * step * (c0 - c2) / denom
                # The frequency's deviation from the misfit's curvature about its least (one unit of misfit per
                # deviation, scaled by how much worse than the noise the sway fits); never above the resolution.
                scale = max(1.0, c1 / max(z.size - 10, 1))
                sd = min(sd, step * np.sqrt(2.0 * scale / denom))
        sway = replace(self._solve(t - t0, z, v, best), frequency_sd=float(sd))
        w = 1.0 / v
        misfit_still = float(np.sum(w * (z - np.sum(w * z, axis=0) / np.sum(w, axis=0)) ** 2))
        if misfit_still - float(np.min(chi)) < self.s.significance:
            return still
        return sway

    @staticmethod
    def _chi2(t, z, v, grid):
        """(K,): the misfit of a sway at each frequency of ``grid`` (K,) Hz, its first harmonic alone (with the
        second, half the frequency would fit as well); all at once."""
        w = 1.0 / v.T
        _, _, r = _weighted_fit(_terms(t, grid)[:, :, :3], z, w)
        return (r * r * w[None]).sum(axis=(1, 2))

    def _solve(self, t, z, v, f):
        X = _design(t, f)
        n, p = X.shape
        w = 1.0 / v.T
        beta, A, r = (x[0] for x in _weighted_fit(X[None], z, w))
        coeffs, cov = np.zeros((3, 5)), np.zeros((3, 5, 5))
        coeffs[:, :p] = beta
        # The residuals' degrees of freedom: the frequency, searched for, was fitted to them too.
        dof = max(n - p - (1 if f > 0 else 0), 1)
        # Scaled by how much worse than the noise the model fits (a gust, a sway off the model): at least 1.
        scale = np.maximum(1.0, (w * r * r).sum(axis=1) / dof)
        cov[:, :p, :p] = np.linalg.inv(A) * scale[:, None, None]
        # How far the apple strays from the model beyond the noise: over the window, or lately (a gust begun).
        recent = t >= t[-1] - self.s.recent
        stray = np.maximum((r * r).sum(axis=1), (r[:, recent] ** 2).mean(axis=1) * n) / dof - v.mean(axis=0)
        rms = np.sqrt(np.maximum(0.0, stray)) if n > p else np.zeros(3)
        return Fit(coeffs, cov, float(f), self.t, rms, float(t[-1] - t[0]) if n else 0.0)


class Sightings:
    """A camera's recent frames: each one's stamp (s), the apples' centres it saw ((N, 3) m) and their diameters
    ((N,) m), the last ``window`` s of them. A pick's goal comes after the camera has watched its apple for a while:
    those frames fit its motion at once, instead of from the goal on."""

    def __init__(self, window=SwaySettings().window):
        self.window = window
        self._frames = collections.deque()

    def add(self, t, places, diameters):
        self._frames.append((float(t), np.asarray(places, float).reshape(-1, 3), np.asarray(diameters, float)))
        while self._frames[0][0] < t - self.window:
            self._frames.popleft()

    def of(self, p, radius):
        """``(t, centre, diameter)`` of one apple in each frame that saw it, oldest first: followed back from the
        newest frame's apple nearest ``p`` (3,) within ``radius`` m, each earlier frame's nearest to the place taken
        after it, within TRACK_GATE m and the way an apple at TRACK_SPEED goes in between (an apple carried past by
        the arm, another's, is not taken for it)."""
        out, ref, after = [], np.asarray(p, float), None
        for t, places, diameters in reversed(self._frames):
            if not len(places):
                continue
            d = np.linalg.norm(places - ref, axis=1)
            k = int(np.argmin(d))
            if d[k] <= (radius if after is None else TRACK_GATE + TRACK_SPEED * (after - t)):
                out.append((t, places[k], diameters[k]))
                ref, after = places[k], t
        return out[::-1]
