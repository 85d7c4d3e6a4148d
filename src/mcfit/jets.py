"""Forward-mode differentiation of the few scalars of a closed-form motion
(:mod:`mcfit.viscous_motion`, :mod:`mcfit.hysteretic_motion`): each scalar carries its
gradient with respect to the motion's parameters. numpy only."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Jet"]


class Jet:
    """A scalar and its gradient with respect to a few parameters (forward-mode
    differentiation of the few scalars of a closed-form solution)."""

    __slots__ = ("v", "g")

    def __init__(self, value, gradient):
        self.v, self.g = float(value), gradient

    @classmethod
    def variables(cls, values):
        """The parameters ``values``, each a Jet of gradient 1 in its own direction."""
        unit = np.eye(len(values))
        return tuple(cls(value, unit[i]) for i, value in enumerate(values))

    @staticmethod
    def _of(other):
        return other if isinstance(other, Jet) else Jet(other, 0.0)

    def __add__(self, other):
        other = self._of(other)
        return Jet(self.v + other.v, self.g + other.g)

    def __sub__(self, other):
        other = self._of(other)
        return Jet(self.v - other.v, self.g - other.g)

    def __neg__(self):
        return Jet(-self.v, -self.g)

    def __mul__(self, other):
        other = self._of(other)
        return Jet(self.v * other.v, self.g * other.v + other.g * self.v)

    __rmul__ = __mul__

    def __truediv__(self, other):
        other = self._of(other)
        value = self.v / other.v
        return Jet(value, (self.g - other.g * value) / other.v)

    def __rtruediv__(self, other):
        return self._of(other) / self

    def sqrt(self):
        value = math.sqrt(self.v)
        return Jet(value, self.g / (2 * value))

    def log(self):
        return Jet(math.log(self.v), self.g / self.v)

    def exp(self):
        value = math.exp(self.v)
        return Jet(value, self.g * value)

    def cos(self):
        return Jet(math.cos(self.v), -math.sin(self.v) * self.g)

    def sin(self):
        return Jet(math.sin(self.v), math.cos(self.v) * self.g)

    @staticmethod
    def atan2(y, x):
        radius = x.v * x.v + y.v * y.v
        return Jet(math.atan2(y.v, x.v), (x.v * y.g - y.v * x.g) / radius)
