"""Current-measurement effects: delay, first-order lag, drive-gain (torque constant) error, offset."""

from __future__ import annotations

from collections import deque

import numpy as np

from urident.simcontroller.effects.base import Effect
from urident.simcontroller.effects.params import Param


class CurrentDelay(Effect):
    name = "current_delay"
    summary = "current measurement delay: the reported current is the current d seconds earlier"
    details = ("i_reported(t) = i(t − d), linearly interpolated between controller samples; before "
               "the first sample the first value holds. Stateful: keeps the last d seconds.")
    params = (Param("delay_s", "joint", 0.003, "delay d [s]", low=0.0, high=1.0),)
    hook = "current"
    stateful = True
    needs_robot = False

    def reset(self) -> None:
        self._delay = self.value("delay_s")
        self._max_delay = float(np.max(self._delay[list(self.joints)]))
        self._times: deque[float] = deque()
        self._values: deque[np.ndarray] = deque()

    def current(self, t, current, q, qd, temperatures):
        t = float(t)
        current = np.asarray(current, dtype=float)
        self._times.append(t)
        self._values.append(current.copy())
        # keep one sample at or before the oldest time still needed
        while len(self._times) > 2 and self._times[1] <= t - self._max_delay:
            self._times.popleft()
            self._values.popleft()
        times = np.fromiter(self._times, dtype=float, count=len(self._times))
        values = np.array(self._values)
        out = current.copy()
        for j in self.joints:
            out[j] = np.interp(t - self._delay[j], times, values[:, j])
        return out

    def offline_current(self, t, current, q, qd, temperatures):
        out = np.array(current, dtype=float)
        for j in self.joints:
            out[:, j] = np.interp(t - self._delay[j], t, current[:, j])
        return out


def first_order_lag(t: np.ndarray, x: np.ndarray, tau) -> np.ndarray:
    """``x`` (N,) or (N, k) through 1/(τs + 1) along the times ``t`` (N,), exact for a signal held
    between samples (``tau`` a scalar or one per column); the output starts at the first sample
    (at rest before it)."""
    x = np.asarray(x, dtype=float)
    dt = np.diff(np.asarray(t, float))
    tau = np.maximum(np.asarray(tau, float), 1e-12)
    if len(x) < 2:
        return x.copy()
    if np.ptp(dt) <= 1e-9 * abs(dt[0]) and tau.ndim == 0:   # a constant period: one IIR filter
        from scipy.signal import lfilter

        a = float(np.exp(-dt[0] / tau))
        return lfilter([1.0 - a], [1.0, -a], x, axis=0, zi=a * x[:1])[0]   # y[-1] = x[0]
    y = x.copy()
    a = np.exp(-dt.reshape((-1,) + (1,) * (x.ndim - 1)) / tau)
    for k in range(1, len(y)):
        y[k] = a[k - 1] * y[k - 1] + (1.0 - a[k - 1]) * y[k]
    return y


class CurrentLag(Effect):
    name = "current_lag"
    summary = "first-order current lag: the reported current is the current through 1/(τs + 1)"
    details = ("i_reported = i / (τ·s + 1), a current-loop or measurement filter: unlike a pure delay it "
               "attenuates as it lags (phase −atan(ωτ), gain 1/√(1 + ω²τ²)), the sensor noise too. "
               "Stateful: keeps the last reported value.")
    params = (Param("time_constant_s", "joint", 0.005, "time constant τ [s]", low=0.0, high=1.0),)
    hook = "current"
    stateful = True
    needs_robot = False

    def reset(self) -> None:
        self._tau = self.value("time_constant_s")
        self._t: float | None = None
        self._y: np.ndarray | None = None

    def current(self, t, current, q, qd, temperatures):
        t = float(t)
        current = np.asarray(current, dtype=float)
        if self._y is None:
            self._y = current.copy()
        else:
            a = np.exp(-(t - self._t) / np.maximum(self._tau, 1e-12))
            self._y = a * self._y + (1.0 - a) * current
        self._t = t
        return np.where(self.mask, self._y, current)

    def offline_current(self, t, current, q, qd, temperatures):
        current = np.asarray(current, dtype=float)
        return np.where(self.mask, first_order_lag(t, current, self._tau), current)


class TorqueConstantError(Effect):
    name = "torque_constant_error"
    summary = "the true drive gain (gear ratio × torque constant) differs from the robot file's"
    details = ("true gain = gain_factor × robot-file gain, so the drive needs, and reports, "
               "i = τ / (gain_factor · k_file): the reported current is divided by gain_factor.")
    params = (Param("gain_factor", "joint", 1.05, "true / robot-file drive gain [-]",
                    low=0.0, low_inclusive=False, high=10.0),)
    hook = "current"
    needs_robot = False

    def reset(self) -> None:
        self._factor = self.value("gain_factor", 1.0)

    def _stateless_current(self, t, current, q, qd, temperatures):
        return current / self._factor


class CurrentOffset(Effect):
    name = "current_offset"
    summary = "constant offset in the measured current"
    details = "i_reported = i + offset_a."
    params = (Param("offset_a", "joint", 0.05, "offset [A]", low=-20.0, high=20.0),)
    hook = "current"
    needs_robot = False

    def reset(self) -> None:
        self._offset = self.value("offset_a")

    def _stateless_current(self, t, current, q, qd, temperatures):
        return current + self._offset
