"""Coupon tests of the thin-fabric shells ([J], MODELS 5 and 6.1) with the T300-3K presets: uniaxial tension, bias
extension, three-point bending of 40 mm squares along the yarns and at 45 deg for `sm` and `ts`.

    python studies/shell_coupons.py run [COUPON ...]    # fdeck run of decks/coupons/*.yaml (curves)
    python studies/shell_coupons.py table [sm ts]       # mesh-size study of the bending coupons (fdeck run each)
    python studies/shell_coupons.py report              # tables + pictures from existing results only

Results go to results/shell_coupons/; tables to studies/out/shell_coupons.md, pictures to docs/img/shell_*.png.

Mesh study: for each bending coupon and element size (4, 2, 1 mm on the 20 mm quarter), the coupon deck with a
small central load instead of the 4 mm stroke (deflection ~ span / 200, so small-deflection theory applies),
brought to rest by mass-proportional damping at twice its first frequency (3 first periods: ramp over 1.5, then
settle; the remaining kinetic energy is reported). The centre deflection is compared with the closed forms of
MODELS 5 evaluated with the presets: Euler-Bernoulli (sm, EI along the yarns; at 45 deg the narrow-strip value
1 / (1/(2 EI) + 1/(4 GI)), with the plate value EI/2 + GI as the other bound) and Timoshenko with
alpha P l / (4 G A) (ts; at 45 deg the strip of the +-45 fabric, whose membrane modulus through the thickness is
1 / (1/(2 E_f) + 1/(4 G12)) on each side of the neutral axis).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks" / "coupons"
RESULTS = ROOT / "results" / "shell_coupons"
OUT = ROOT / "studies" / "out"
IMG = ROOT / "docs" / "img"
BENDING = ["bending_sm_0", "bending_sm_45", "bending_ts_0", "bending_ts_45"]
COUPONS = ["tension_sm", "bias_extension_sm"] + BENDING
SPAN, WIDTH, ALPHA = 32.0, 40.0, 1.2


# ------------------------------------------------------------------------------------------------ closed forms

def presets():
    """Numbers of the presets the closed forms need (read from the preset files, not repeated here)."""
    from fdeck.cards.shell_sections import load_section_preset
    from fdeck.cards.fabric_membrane import load_preset

    sm, ts = load_section_preset("sm", "t300_3k"), load_section_preset("ts", "t300_3k")
    mat_ts = load_preset("t300_3k_ts")
    Et = mat_ts["warp"]["tension"][1][1] / mat_ts["warp"]["tension"][1][0]
    Ec = mat_ts["warp"]["compression"][1][1] / mat_ts["warp"]["compression"][1][0]
    shear = mat_ts["shear"]["curve"]
    G12 = shear[1][1] / math.radians(shear[1][0])  # initial slope of the shear curve [MPa/rad]
    return dict(EI=sm["bending_stiffness"], GI=sm["twisting_stiffness"], h=ts["thickness"], Et=Et, Ec=Ec,
                G12=G12, G13=ts["transverse_shear_modulus"], kappa=ts["shear_correction"],
                density=load_preset("t300_3k")["density"])


def bimodulus(Et, Ec, h):
    return 4 * Et * Ec / (math.sqrt(Et) + math.sqrt(Ec)) ** 2 * h**3 / 12


def compliance(coupon):
    """(delta / P [mm/N] of the whole coupon, description, plate bound or None) from MODELS 5's closed forms.

    Along the yarns the coupon bends cylindrically (no Poisson coupling, D12 = 0): one closed form. At 45 deg the
    narrow strip (anticlastic curvature free) is the soft bound and the plate in cylindrical bending (curvature
    across held at zero, as the line supports do where they hold w = 0) the stiff one; the square lies between.
    sm: EI_45 = 1 / (1/(2 EI) + 1/(4 GI)) and EI/2 + GI. ts: the +-45 fabric's membrane modulus is
    1 / (1/(2 E_f) + 1/(4 G12)) free (trellising) and E_f / 2 + G12 held (fibres stretch), on each side of the
    neutral axis with E_f the tension or compression slope.
    """
    p = presets()
    l, b, h = SPAN, WIDTH, p["h"]
    bend = l**3 / (48 * b)
    if coupon == "bending_sm_0":
        return bend / p["EI"], "Euler-Bernoulli, EI", None
    if coupon == "bending_sm_45":
        strip = 1 / (1 / (2 * p["EI"]) + 1 / (4 * p["GI"]))
        return bend / strip, "Euler-Bernoulli, strip EI_45", bend / (p["EI"] / 2 + p["GI"])
    shear = ALPHA * l / (4 * p["G13"] * b * h)
    if coupon == "bending_ts_0":
        return bend / bimodulus(p["Et"], p["Ec"], h) + shear, "Timoshenko, bimodulus EI", None
    free = [1 / (1 / (2 * E) + 1 / (4 * p["G12"])) for E in (p["Et"], p["Ec"])]
    held = [E / 2 + p["G12"] for E in (p["Et"], p["Ec"])]
    return (bend / bimodulus(*free, h) + shear, "Timoshenko, strip of the +-45 fabric",
            bend / bimodulus(*held, h) + shear)


def first_period(coupon):
    """First period [s] of the simply supported coupon from its closed-form compliance (mass rho h b l / 2); at
    45 deg from the geometric mean of the two bounds."""
    p = presets()
    c, _, plate = compliance(coupon)
    k = 1 / (c if plate is None else math.sqrt(c * plate))
    m = p["density"] * p["h"] * WIDTH * SPAN / 2  # modal mass of a simply supported beam's first mode: half
    return 2 * math.pi * math.sqrt(m / k)


# ------------------------------------------------------------------------------------------------ runs

def fdeck_run(deck: Path, out: Path) -> dict:
    subprocess.run([sys.executable, "-m", "fdeck.cli", "run", str(deck), "-o", str(out)], check=False)
    return json.loads((out / "summary.json").read_text())


def variant(coupon: str, size: float) -> Path:
    """The coupon deck at element size ``size`` with a small central load brought to rest (see the docstring)."""
    from fdeck.deck.loader import load_file

    data, _ = load_file(DECKS / f"{coupon}.yaml")
    data["mesh"]["plate"]["element_size"] = size
    P = SPAN / 200 / compliance(coupon)[0]
    T1 = first_period(coupon)
    w1 = 2 * math.pi / T1
    data["title"] += f" (mesh study, {size:g} mm, load {P:.3g} N)"
    data["boundary"] = [c for c in data["boundary"] if c["type"] != "displacement"]
    data["amplitudes"] = {"load": {"type": "smooth_step", "t1": 1.5 * T1}}
    data["loads"] = [{"type": "nodal_force", "nodes": "xmin", "force": [0, 0, -P / 4], "distribution": "total",
                      "amplitude": "load"}]
    data["steps"] = [{"name": "load and settle", "duration": 3 * T1, "damping": {"mass_proportional": 2 * w1}}]
    data["output"] = {"frames": 1, "formats": ["vtu"], "history_points": 100, "reactions": ["support"],
                      "measures": [{"type": "node_displacement", "name": "deflection", "nodes": "xmin",
                                    "component": "z"}]}
    data["checks"] = {"energy_balance": {"max_error": 0.01}}
    folder = RESULTS / "variants"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{coupon}_{size:g}mm.yaml"
    text = "# yaml-language-server: $schema=../../../schemas/deck.schema.json\n" + \
        f"# Generated by studies/shell_coupons.py from decks/coupons/{coupon}.yaml.\n" + \
        yaml.safe_dump(data, sort_keys=False)
    path.write_text(text)
    return path


SIZES = {"bending_sm_0": (4.0, 2.0, 1.0), "bending_ts_0": (4.0, 2.0, 1.0),
         "bending_sm_45": (4.0, 2.0, 1.0), "bending_ts_45": (4.0, 2.0, 1.0)}


def run_table(which):
    for coupon in BENDING:
        if which and not any(w in coupon for w in which):
            continue
        for size in SIZES[coupon]:
            deck = variant(coupon, size)
            fdeck_run(deck, RESULTS / "variants" / deck.stem)


# ------------------------------------------------------------------------------------------------ report

def history(folder: Path):
    from fdeck.io.history import read_history

    return read_history(folder / "history.csv")


def table_rows():
    rows = ["| coupon | reference | element [mm] | elements (quarter) | deflection / reference | "
            "deflection / plate bound | KE / IE at end | energy balance | wall [s] | us / element-cycle |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for coupon in BENDING:
        ref, what, other = compliance(coupon)
        for size in SIZES[coupon]:
            folder = RESULTS / "variants" / f"{coupon}_{size:g}mm"
            if not (folder / "summary.json").exists():
                continue
            s = json.loads((folder / "summary.json").read_text())
            h = history(folder)
            P = SPAN / 200 / ref
            ratio = -h["deflection"][-1] / (P * ref)
            bal = next((c["value"] for c in s["checks"] if c["name"] == "energy_balance"), float("nan"))
            plate = f"{-h['deflection'][-1] / (P * other):.4f}" if other else "-"
            rows.append(f"| {coupon} | {what} | {size:g} | {s['elements']} | {ratio:.4f} | {plate} | "
                        f"{h['kinetic_energy'][-1] / h['internal_energy'][-1]:.1e} | {bal:.1e} | "
                        f"{s['wall_time']:.0f} | {s['us_per_element_cycle']:.2f} |")
    return "\n".join(rows)


def plots():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from fdeck.cards.fabric_membrane import load_preset

    IMG.mkdir(parents=True, exist_ok=True)
    lines = []
    # tension: force against strain, and the card's curve
    f = RESULTS / "tension_sm"
    if (f / "history.csv").exists():
        h = history(f)
        mat = load_preset("t300_3k")
        pts = np.array(mat["warp"]["tension"])
        lam = 1 + h["elongation"] / 80.0
        E = (lam**2 - 1) / 2
        S = np.interp(E, pts[:, 0], pts[:, 1])
        beyond = E > pts[-1, 0]
        S[beyond] = pts[-1, 1] + (pts[-1, 1] - pts[-2, 1]) / (pts[-1, 0] - pts[-2, 0]) * (E[beyond] - pts[-1, 0])
        card = 24 * presets()["h"] * lam * S
        fig, ax = plt.subplots(figsize=(5, 3.6))
        ax.plot(100 * E, h["reaction_xmax_x"], label="fdeck sm, 2 mm")
        ax.plot(100 * E, card, "k--", label="card curve: b h lambda S(E)")
        ax.set_xlabel("Green-Lagrange strain [%]")
        ax.set_ylabel("force [N]")
        ax.set_title("uniaxial tension, 80 x 24 mm")
        ax.legend()
        fig.tight_layout()
        fig.savefig(IMG / "shell_tension.png", dpi=130)
        plt.close(fig)
        late = E > 0.005
        lines.append(f"Uniaxial tension: force / (b h lambda S(E)) over strains 0.5-2 %: "
                     f"{(h['reaction_xmax_x'][late] / card[late]).min():.4f} to "
                     f"{(h['reaction_xmax_x'][late] / card[late]).max():.4f}.")
    # bias extension
    f = RESULTS / "bias_extension_sm"
    if (f / "history.csv").exists():
        h = history(f)
        lines += bias_report(h, plt, np)
    # bending curves
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for coupon, ax in zip(("bending_sm", "bending_ts"), axes):
        for angle, style in (("0", "-"), ("45", "--")):
            f = RESULTS / f"{coupon}_{angle}"
            if not (f / "history.csv").exists():
                continue
            h = history(f)
            d, P = -h["deflection"], -4 * h["reaction_xmin_z"]
            ax.plot(d, 1e3 * P, style, label=f"{angle} deg, fdeck")
            ref, _, plate = compliance(f"{coupon}_{angle}")
            ax.plot([0, 1.0], [0, 1e3 / ref], ":", color=ax.lines[-1].get_color(),
                    label=f"{angle} deg, small deflection" + (", strip" if plate else ""))
            if plate:
                ax.plot([0, 1.0], [0, 1e3 / plate], "-.", color=ax.lines[-1].get_color(),
                        label=f"{angle} deg, small deflection, plate")
        ax.set_xlabel("central deflection [mm]")
        ax.set_ylabel("force [mN]")
        ax.set_title(f"three-point bending, {coupon[-2:]}")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(IMG / "shell_bending.png", dpi=130)
    plt.close(fig)
    return lines


def bias_report(h, plt, np):
    """Central shear angle against the pin-jointed net; shear stress by MODELS 6.1's normalisation against the
    card's tau / cos(gamma) (tau = dPhi/dgamma per reference volume, sigma_12 per current area: see the law)."""
    from fdeck.cards.fabric_membrane import load_preset

    W, H, t = 30.0, 120.0, presets()["h"]
    d, F = h["clamp_travel"], h["reaction_GRIP_HIGH_y"]
    g_pj = np.radians(h["pin_jointed_shear_angle"])
    ok = np.isfinite(g_pj) & (d > 0.2)
    d, F, g_pj, g_sim = d[ok], F[ok], g_pj[ok], np.radians(h["central_shear_angle"][ok])

    def sigma12(g, memo={}):
        """MODELS 6.1 recursion from small angles, F interpolated at the travel giving angle g."""
        if g < math.radians(0.5):
            return 0.0
        Fg = np.interp(g, g_pj, F)
        return ((H / W - 1) * Fg * (math.cos(g / 2) - math.sin(g / 2)) - W * sigma12(g / 2) * math.cos(g / 2) * t) \
            / ((2 * H - 3 * W) * t * math.cos(g))

    mat = load_preset("t300_3k")["shear"]
    curve = np.array(mat["curve"], float)
    lock, G_lock = math.radians(mat["locking_angle"]), mat["locking_modulus"]

    def tau(g):
        if g <= lock:
            return np.interp(math.degrees(g), curve[:, 0], curve[:, 1])
        return np.interp(mat["locking_angle"], curve[:, 0], curve[:, 1]) + G_lock * (g - lock)

    angles = np.radians(np.arange(2.0, 50.0, 2.0))
    angles = angles[angles < g_pj.max()]
    rec = np.array([sigma12(g) for g in angles])
    card = np.array([tau(g) / math.cos(g) for g in angles])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
    a1.plot(d, np.degrees(g_sim), label="fdeck sm, central zone")
    a1.plot(d, np.degrees(g_pj), "k--", label="pin-jointed net")
    a1.set_xlabel("clamp travel [mm]")
    a1.set_ylabel("shear angle [deg]")
    a1.legend()
    a2.plot(np.degrees(angles), rec, "o-", ms=3, label="from the force (MODELS 6.1)")
    a2.plot(np.degrees(angles), card, "k--", label="card: tau / cos(gamma)")
    a2.set_xlabel("shear angle [deg]")
    a2.set_ylabel("shear stress sigma_12 [MPa]")
    a2.set_yscale("log")
    a2.legend()
    fig.tight_layout()
    fig.savefig(IMG / "shell_bias_extension.png", dpi=130)
    plt.close(fig)
    rows = ["| clamp travel [mm] | pin-jointed [deg] | central zone [deg] | force [N] |", "|---|---|---|---|"]
    for travel in (5, 10, 15, 20, 25, 30):
        if travel <= d.max():
            rows.append(f"| {travel} | {math.degrees(np.interp(travel, d, g_pj)):.1f} | "
                        f"{math.degrees(np.interp(travel, d, g_sim)):.1f} | {np.interp(travel, d, F):.3f} |")
    rows += ["", "| shear angle [deg] | sigma_12 from the force [MPa] | card tau / cos(gamma) [MPa] | ratio |",
             "|---|---|---|---|"]
    for g, r, c in zip(angles[::2], rec[::2], card[::2]):
        rows.append(f"| {math.degrees(g):.0f} | {r:.4f} | {c:.4f} | {r / c:.3f} |")
    return rows


def report():
    OUT.mkdir(parents=True, exist_ok=True)
    text = ["## Bending coupons: mesh size against the closed forms", "", table_rows(), ""]
    text += plots()
    text = "\n".join(text) + "\n"
    (OUT / "shell_coupons.md").write_text(text)
    return text


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["run", "table", "report"])
    ap.add_argument("which", nargs="*")
    args = ap.parse_args()
    if args.mode == "run":
        for c in args.which or COUPONS:
            fdeck_run(DECKS / f"{c}.yaml", RESULTS / c)
    elif args.mode == "table":
        run_table(args.which)
    print(report())


if __name__ == "__main__":
    main()
