"""Human-readable accounts of results, for the command line and notebooks."""

from __future__ import annotations

import math
from html import escape

from baslip.model.quantities import UNITS


def summary_text(result) -> str:
    """A short human-readable account of a result."""
    a, c = result.apex, result.control
    deg = 180 / math.pi
    lines = [
        f"{result.name}: {result.status} ({result.message})",
        f"  IPOPT {result.solver.return_status} in {result.solver.iterations} iterations, "
        f"Newton polish {result.polish_iterations} steps, {result.solver.time_s:.2f} s",
        f"  compile  {result.solver.compile_s:.2f} s (code generation, gcc and loading of the compiled libraries)",
        f"  apex     z = {a['z']:.6f} m, theta_h = {a['theta_h'] * deg:.4f} deg, "
        f"ydot = {a['ydot']:.6f} m/s, theta_h_dot = {a['theta_h_dot'] * deg:.4f} deg/s",
        f"  control  {_controls_text(c, result.law.units)}" + ("" if result.law.name == "pd" else f" ({result.law.name})"),
        f"  energy   {result.energy:.9g} J",
    ]
    lines += _explained(result)
    if result.orbit is not None:
        apexes = "; ".join(f"z = {X[0]:.6f} m, ydot = {X[2]:.6f} m/s" for X in result.orbit)
        lines.append(f"  orbit    {result.strides} strides, apexes: {apexes}")
    if result.residual is not None:
        lines.append(f"  residual eps = {result.residual:.3e} ({result.residual_source})")
    if result.stability is not None:
        parts = []
        # Largest modulus first, the one that decides stability; the files keep the
        # eigenvalue solver's order.
        for m in sorted(result.stability.multipliers, key=lambda m: -abs(m.value)):
            text = f"{m.value.real:.6g}{m.value.imag:+.6g}j" if m.value.imag else f"{m.value.real:.6g}"
            parts.append(f"{text} [{m.label}]" if m.label else text)
        verdict = "stable" if result.stable else "unstable"
        of_map = "" if result.strides == 1 else f" (of the {result.strides}-stride map)"
        lines.append(f"  multipliers{of_map} {', '.join(parts)}")
        lines.append(f"  spectral radius {result.spectral_radius:.6g} -> {verdict}")
    return "\n".join(lines)


def _explained(result) -> list[str]:
    """The lines that explain a result: IPOPT's tries when there were several, the
    quantities on a bound, and a failure's diagnosis (binding limits, suggestions)."""
    lines = []
    if len(result.solver.tries) > 1:
        lines.append("  IPOPT: " + "; ".join(t.text(n) for n, t in enumerate(result.solver.tries, start=1)))
    if result.on_bounds:
        lines.append("  on bound " + "; ".join(limit.text() for limit in result.on_bounds))
    if result.diagnosis is not None:
        lines += result.diagnosis.lines()
    return lines


def _controls_text(control: dict[str, float], units) -> str:
    """``name = value unit`` of each control, angles [rad] and rates [rad/s] in degrees."""
    return ", ".join(_control_text(name, value, units[name]) for name, value in control.items())


def _control_text(name: str, value: float, unit: str) -> str:
    if unit.startswith("rad"):
        return f"{name} = {math.degrees(value):.4f} deg{unit[len('rad'):]}"
    return f"{name} = {value:.6g} {unit}"


def html_table(result) -> str:
    """The result as a small HTML table, for notebooks: angles in degrees."""
    rows = [("status", f"{result.status} ({result.message})")]
    rows += [_html_quantity(n, v) for n, v in {**result.apex, **result.control}.items()]
    rows += [("energy [J]", f"{result.energy:.6g}")]
    if result.residual is not None:
        rows.append(("residual eps", f"{result.residual:.2e}"))
    if result.stability is not None:
        rows.append(("multipliers", ", ".join(f"{m.value:.4g}" for m in result.stability.multipliers)))
        rows.append(("spectral radius", f"{result.spectral_radius:.6g} ({'stable' if result.stable else 'unstable'})"))
    body = "".join(f"<tr><th style='text-align:left'>{escape(k)}</th><td>{escape(v)}</td></tr>" for k, v in rows)
    return (f"<b>{escape(result.name)}</b><table>{body}</table><small>angles in degrees; Python values (result.apex, "
            "result.control) are SI units and radians</small>")


def _html_quantity(name: str, value: float) -> tuple[str, str]:
    """(``name [unit]``, value) of a row of the HTML table: angles in degrees, as people read them."""
    unit = UNITS[name]
    if unit.startswith("rad"):
        return f"{name} [deg{unit[len('rad'):]}]", f"{math.degrees(value):.6g}"
    return f"{name} [{unit}]", f"{value:.6g}"
