"""Classic benchmark models (../shared/seeds/benchmarks-public.md)."""
import sympy as sp

from ocdsl.symbolic.model import Model, sym, syms
from ocdsl.symbolic.registry import register


@register("double_integrator", description="x' = v, v' = u")
def double_integrator(options) -> Model:
    x, v = syms("x v")
    u = sym("u")
    return Model("double_integrator", (x, v), (u,), {x: v, v: u},
                 units={"x": "m", "v": "m/s", "u": "m/s^2"}, positions=("x",))


@register("brachistochrone", description="bead on a wire: x' = v sin(theta), y' = -v cos(theta), v' = g cos(theta)")
def brachistochrone(options) -> Model:
    x, y, v, theta, g = syms("x y v theta g")
    return Model("brachistochrone", (x, y, v), (theta,),
                 {x: v * sp.sin(theta), y: -v * sp.cos(theta),
                  v: g * sp.cos(theta)},
                 parameters={g: 9.80665}, units={"x": "m", "y": "m", "v": "m/s", "theta": "rad"},
                 positions=("x", "y"))
