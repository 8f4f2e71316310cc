"""The text of `air-hockey sysid`'s report and the parameter YAML it writes (:mod:`.sysid` runs the
identification): the thesis-style tables (tables 5.2-5.4), the split identification's fits with standard
errors, the warnings on rims met off their lines and on table geometry found but not moved."""
from __future__ import annotations

import math
from pathlib import Path

from air_hockey_agent.core.identification.local_fit import beyond_noise
from air_hockey_agent.params import yaml_value
from air_hockey_agent.tools.files import write_text_atomic


def rims_off(result: dict, limit: float, significance: float) -> list[str]:
    """The rims whose impacts' paths meet farther than ``limit`` [m] (and ``significance`` standard errors)
    from the model's rim line at no speed (split's delay fit, on the moved rims after table_geometry), in
    words."""
    delay = result.get("objective", {}).get("impacts", {}).get("delay")
    if delay is None:
        return []
    return [f"the {rim} rim's impacts meet {offset * 1e3:+.2f} +- {delay['offset_std_m'][rim] * 1e3:.2f} mm from "
            f"the model's rim line ({'inside' if offset > 0 else 'beyond'} it)"
            for rim, offset in delay["offsets_m"].items()
            if beyond_noise(offset, delay["offset_std_m"][rim], significance, limit)]


def geometry_warnings(geometry: dict | None, settings: dict) -> list[str]:
    """What of the table's geometry was found but not moved: beyond its bounds, or a centre the poses' own
    transform fixes (--table-frame, table-frame poses)."""
    if not geometry:
        return []
    values = {**geometry["values_m"], "yaw": geometry["yaw_rad"]}
    errors = {**geometry["std_m"], "yaw": geometry["yaw_std_rad"]}
    out = [f"the rims' {part} is {_part_text(part, values[part])} from the configured table's, beyond "
           f"bounds.{'table_yaw' if part == 'yaw' else 'table_geometry'} (config/sysid.yaml): not moved; the "
           f"table's configuration (config/table.yaml, mocap_table_pose) looks wrong, not its calibration"
           for part, beyond in geometry["beyond"].items() if beyond]
    pose_parts = ("centre_x", "centre_y", "yaw")
    if not geometry["centre_movable"] and any(values[part] is not None and
                                              beyond_noise(values[part], errors[part], settings["split.significance"])
                                              for part in pose_parts):
        out.append(f"the rims' centre is ({_mm(values['centre_x'])}, {_mm(values['centre_y'])}) mm from "
                   f"the table frame's origin and turned {_mm(values['yaw'])} mrad, but the poses did not come "
                   f"through one table pose (bags with different transforms to --table-frame, or poses in the "
                   f"table frame): move the table's transform by that; only the size was moved")
    return out


def _part_text(part: str, value: float) -> str:
    return f"{value * 1e3:+.2f} mrad" if part == "yaw" else f"{value * 1e3:+.1f} mm"


def _mm(value: float | None, sign: str = "+") -> str:
    """[m] (or [rad]) as mm (mrad) text; "?" for a part whose two rims were not both met."""
    return "?" if value is None else f"{value * 1e3:{sign}.2f}"


def objective_text(loss: str, value: float) -> str:
    """The optimised objective as the report shows it: the position loss in mm, the log-likelihood as is."""
    return f"{value * 1e3:.2f} mm" if loss == "position" else f"{value:.6g}"


def format_report(result: dict, out: Path | None) -> str:
    """Thesis-style tables: parameters with loss/min/median before and after; table 5.4 if asked."""
    if result.get("method") == "split":
        return _format_split(result, out)
    names = list(result["identified"])
    width = max(17, *(len(n) + 2 for n in names))
    head = (f"{'':<22}" + "".join(f"{n:>{width}}" for n in names)
            + f"{'loss [mm]':>11}{'traj. min [mm]':>16}{'traj. median [mm]':>19}")
    lines = [f"loss {result['loss']}, horizon {result['horizon']} s, {result['evaluations']} evaluations in "
             f"{result['seconds']} s", head]
    for label, params, key in (("initial (train)", result["initial"], "before"),
                               ("identified (train)", result["identified"], "after")):
        for subset in ("train", "validation"):
            r = result[key][subset]
            tag = label.replace("(train)", f"({subset})")
            lines.append(f"{tag:<22}" + "".join(f"{params[n]:>{width}.6g}" for n in names)
                         + f"{r['loss_m'] * 1e3:>11.2f}{r['min_m'] * 1e3:>16.2f}{r['median_m'] * 1e3:>19.2f}")
    o = result["objective"]
    lines.append(f"optimised objective ({o['loss']} loss at {o['horizon']} s on the training set, predictions "
                 f"from every {o['stride']}. frame with a state): {objective_text(o['loss'], o['initial'])} -> "
                 f"{objective_text(o['loss'], o['identified'])}")
    before, after = result["before"]["validation"]["loss_m"], result["after"]["validation"]["loss_m"]
    if before > 0:
        change = 100.0 * (after - before) / before
        lines.append(f"validation loss {before * 1e3:.2f} -> {after * 1e3:.2f} mm "
                     f"({abs(change):.1f} % {'lower' if change < 0 else 'higher'})")
    if "cross_validation" in result:
        lines.append("cross-validation (thesis table 5.4): validate at / learned at -> loss, min, median [mm]")
        for v, row in result["cross_validation"].items():
            for h, r in row.items():
                lines.append(f"  {v:>4} s / {h:>4} s: {r['loss_m'] * 1e3:8.2f} {r['min_m'] * 1e3:8.2f} "
                             f"{r['median_m'] * 1e3:8.2f}")
    if out is not None:
        lines.append(f"wrote {out}")
    return "\n".join(lines)


def _format_split(result: dict, out: Path | None) -> str:
    """The split identification's values with standard errors, its fits, and the losses before/after."""
    lines = [f"split identification in {result['seconds']} s (reports {result['seconds_with_reports']} s)"]
    for name, value in result["identified"].items():
        std = result["std"].get(name)
        shown = _value_text(value) + ("" if std is None else f" +- {_value_text(std)}")
        lines.append(f"  {name:<20} {_value_text(result['initial'][name]):>22} -> {shown}")
    o = result["objective"]
    if "flight" in o:
        f = o["flight"]
        lines.append(f"flight fit: {f['windows']} windows ({f['dropped']} dropped), acceleration residual RMS "
                     f"{f['rms_acceleration_m_s2']:.4f} m/s^2")
        if "field" in f:
            lines.append(_field_text(f["field"]))
        if "spin_decay" in f:
            lines.append(_spin_text(f["spin_decay"], "spin_damping" in result["identified"], result["significance"]))
    if "impacts" in o:
        i = o["impacts"]
        lines.append(f"impact fit: {i['impacts']} impacts ({i['dropped']} dropped), residual RMS normal "
                     f"{i['rms_normal_speed_m_s']:.4f} m/s, tangential {i['rms_tangential_m_s']:.4f} m/s")
        if "delay" in i:
            lines.append(_delay_text(i["delay"]))
    if "table_geometry" in result:
        lines.append(geometry_text(result["table_geometry"]))
    if "polish" in o:
        p = o["polish"]
        lines.append(f"polish: {p['evaluations']} evaluations of the position loss at {p['horizon']} s (training set, "
                     f"every {p['stride']}. frame): {p['initial_m'] * 1e3:.2f} -> {p['final_m'] * 1e3:.2f} mm")
    lines.extend(f"wrote {path}" for path in result["plots"])
    if result["learning_priors"]:
        lines.append(_priors_text(result["learning_priors"]))
    lines.append(f"prediction loss at {result['horizon']} s (every frame): loss / traj. min / traj. median [mm]")
    for key, label in (("before", "initial"), ("after", "identified")):
        for subset in ("train", "validation"):
            r = result[key][subset]
            lines.append(f"  {label + ' (' + subset + ')':<24}{r['loss_m'] * 1e3:>9.2f}{r['min_m'] * 1e3:>9.2f}"
                         f"{r['median_m'] * 1e3:>9.2f}")
    if out is not None:
        lines.append(f"wrote {out}")
    return "\n".join(lines)


def _field_text(field: dict) -> str:
    """One line on the field check: does the free flight's acceleration vary over the table?"""
    cell = max(field["cells"], key=lambda c: math.hypot(c["ax"], c["ay"]))
    where = (f"largest cell mean {field['largest_m_s2']:.4f} m/s^2 (+- {cell['std_error']:.4f} per axis) at "
             f"({cell['x']:+.2f}, {cell['y']:+.2f}) m, {len(field['cells'])} cells, F {field['f_statistic']:.2f}, "
             f"p {field['p_value']:.2g}")
    if field["varies"]:
        return (f"warning: the free flight's acceleration varies over the table ({where}): an uneven air film "
                f"or a warped surface, which the constant table_acceleration cannot hold")
    return f"table acceleration field: none shown ({where}): the constant table_acceleration suffices"


def _spin_text(spin: dict, identified: bool, significance: float) -> str:
    """One line on the spin's decay in free flight (spin_damping's fit), and whether it was identified."""
    rate, std = spin["rate_per_s"], spin["std_per_s"]
    seen = (f"{rate:.3f} +- {std:.3f} 1/s over {spin['windows']} windows ({spin['dropped']} dropped, RMS spin "
            f"{spin['rms_spin_rad_s']:.2f} rad/s)")
    if not beyond_noise(rate, std, significance):
        return f"spin decay: none shown ({seen}): a constant spin holds"
    if identified:
        return f"spin decay: the spin decays in free flight at {seen}: spin_damping identified"
    return (f"note: the spin decays in free flight at {seen}; spin_damping was not identified (--identify "
            f"spin_damping): the angle's innovations grow with it")


def _delay_text(delay: dict) -> str:
    """One line on where the impacts' paths meet: a compliant rim's delay, and each rim line's offset."""
    offsets = ", ".join(f"{name} {value * 1e3:+.2f} +- {delay['offset_std_m'][name] * 1e3:.2f}"
                        for name, value in delay["offsets_m"].items())
    where = f"{offsets} mm from them (> 0: inside; the table's geometry or pose)"
    if not delay["identified"]:
        return (f"rim contact ({delay['impacts']} impacts): with the configured impact_delay "
                f"{delay['value_s'] * 1e3:.3f} ms the paths before and after meet, at no speed, {where}; their own "
                f"slope: {delay['fitted_s'] * 1e3:.3f} ms x the normal speed beyond the rim lines")
    return (f"rim contact: the paths before and after meet {delay['fitted_s'] * 1e3:.3f} +- {delay['std_s'] * 1e3:.3f} "
            f"ms x the normal speed beyond the rim lines ({delay['impacts']} impacts; impact_delay); at no speed "
            f"{where}")


def geometry_text(geometry: dict) -> str:
    """One line on where the rims were found (table_geometry) and what was moved."""
    v, e = geometry["values_m"], geometry["std_m"]
    found = (f"centre ({_mm(v['centre_x'])}, {_mm(v['centre_y'])}) +- ({_mm(e['centre_x'], '')}, "
             f"{_mm(e['centre_y'], '')}) mm from the table frame's origin, yaw {_mm(geometry['yaw_rad'])} +- "
             f"{_mm(geometry['yaw_std_rad'], '')} mrad, length {_mm(v['length'])} +- {_mm(e['length'], '')} mm, "
             f"width {_mm(v['width'])} +- {_mm(e['width'], '')} mm")
    moved = geometry["parameters"]
    if not moved:
        return f"table geometry: the rims' {found}: none moved (none significant, or beyond its bounds)"
    changes = ", ".join(f"{name} {_geometry_value(value)} (was {_geometry_value(geometry['initial'][name])})"
                        for name, value in moved.items())
    text = f"table geometry: the rims' {found}: moved {changes}; the fits above are on the moved rims"
    if geometry["read_without_table_frame"]:
        text += ("; the moved mocap_table_pose replaces the bags' transform to --table-frame: read them with "
                 "--params-file and without --table-frame")
    return text


def _geometry_value(value) -> str:
    """A table size or pose to 0.01 mm / 0.01 mrad: the geometry moves by millimetres."""
    return ("[" + ", ".join(f"{v:.5f}" for v in value) + "]") if isinstance(value, list) else f"{value:.5f}"


def _priors_text(priors: dict) -> str:
    """One line on the online learning's priors written with the parameters (--out)."""
    parts = {"rim_adaptation.prior_impacts": lambda v: f"the rim law worth {v:g} impacts",
             "acceleration_adaptation.prior_std": lambda v: f"table acceleration +- {v:.2g} m/s^2",
             "acceleration_adaptation.damping_prior_std": lambda v: f"damping +- {v:.2g} 1/s",
             "acceleration_adaptation.friction_prior_std": lambda v: f"surface friction +- {v:.2g} m/s^2",
             "acceleration_adaptation.spin_prior_std": lambda v: f"spin damping +- {v:.2g} 1/s",
             "acceleration_adaptation.marker_offset_prior_std": lambda v: f"marker offset +- {v * 1e3:.2g} mm"}
    return "online learning's priors (with --out): " + ", ".join(parts[n](v) for n, v in priors.items())


def _value_text(value) -> str:
    return ("[" + ", ".join(f"{v:.4g}" for v in value) + "]") if isinstance(value, list) else f"{value:.6g}"


def write_params_yaml(path: Path, values: dict, comment: str, priors: dict | None = None) -> None:
    """Parameter YAML for the puck_tracker, written atomically (temporary file, then rename); ``priors``: the
    online learning's prior weights by dotted name (``rim_adaptation.prior_impacts``, ...), grouped."""
    body = "".join(f"    {name}: {yaml_value(value)}\n" for name, value in values.items())
    groups: dict[str, list[str]] = {}
    for name, value in (priors or {}).items():
        group, key = name.split(".", 1)
        groups.setdefault(group, []).append(f"      {key}: {yaml_value(value)}\n")
    if groups:
        body += ("    # the online learning starts from these values with the identification's own weight: the rim\n"
                 "    # law worth the impacts it was fitted to, the flight's parameters with their standard errors\n")
        body += "".join(f"    {group}:\n" + "".join(lines) for group, lines in groups.items())
    text = f"# Physical parameters of the puck model, {comment}.\n/**/puck_tracker:\n  ros__parameters:\n{body}"
    write_text_atomic(path, text)
