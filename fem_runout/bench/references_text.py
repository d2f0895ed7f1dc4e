"""Text of the benchmark report: formulas and sources, the paper's tables, the reading.

Kept apart from the code that measures the numbers.
"""

from __future__ import annotations

#: Seed Table 1 (relative front errors) and §4.1 text (front positions): e5.5, e11, x5.5, x11.
PAPER_TABLE1 = {"IMEX-TG2-PC (paper)": ("0.0039", "0.0121", "97.3", "240.6"),
                "DAMPM (paper)": ("0.0074", "0.0054", "96.2", "239.2")}
#: Seed Table 2: (DAMPM L1, DAMPM L∞, TG2 L1, TG2 L∞) per variable.
PAPER_TABLE2 = {"h": ("1.26e-12", "1.26e-14", "2.68e-13", "8.92e-15"),
                "hu": ("1.08e-13", "3.57e-14", "2.38e-13", "1.41e-14"),
                "hv": ("1.22e-13", "3.25e-14", "1.67e-13", "2.02e-14")}

REFERENCES = {
    "ritter": (
        "Reference (`fem_runout/references/ritter.py`; Ritter 1892): still layer h0 = 1 m on "
        "x ≤ x0 = 50 m, dry bed beyond, flat and frictionless; with c0 = sqrt(g h0), "
        "h = (2 c0 − (x − x0)/t)²/(9 g) for −c0 t < x − x0 < 2 c0 t, h0 behind, 0 ahead. "
        "Domain 100 m × 2 m, slip walls on the long sides. First order is the best any scheme "
        "reaches here (kinks at both fan edges, a dry front)."),
    "thacker": (
        "Reference (`fem_runout/references/thacker.py`; Thacker 1981, SWASHES §4.2.2 "
        "\"planar surface in a paraboloid\"): bowl Z = −h0 (1 − r²/a²), "
        "h = η h0/a² (2 X cos ωt + 2 Y sin ωt − η) − Z where positive, u = −η ω sin ωt, "
        "v = η ω cos ωt, ω = sqrt(2 g h0)/a; a = 1 m, h0 = 0.1 m, L = 4 m, η = 0.5, period "
        "T = 4.486 s, walls, frictionless. The wet region is the unit disc centred at "
        "η (cos ωt, sin ωt), whose edge (the wet/dry line) moves all the time. The error "
        "is measured after one full period on the nodes at distance ≥ 0.2 m inside that "
        "line (disc of radius 0.8 m), and on the whole domain."),
    "mangeney": (
        "Reference (`fem_runout/references/mangeney.py`; Mangeney et al. 2000, JGR 105, "
        "written for the horizontal-coordinate equations of seed eq. 1): on Z = −S x with "
        "Coulomb friction −g μ h v/|v| (normal stress ρ g h as in `physics/friction.py`) and "
        "u > 0, the momentum source g h (S − μ) is a constant acceleration m = g (S − μ) per "
        "unit mass; in the frame ξ = x − m t²/2, w = u − m t the equations are the flat "
        "frictionless ones, so h = (2 c0 − s)²/(9 g) with s = (x − x0 − m t²/2)/t on "
        "−c0 < s < 2 c0 (Mangeney's formula with cos θ → 1). Here h0 = 1 m on 0 ≤ x ≤ 20 m "
        "(wall at x = 0), S = 0.5, μ = 0.2, t = 2 s; the error excludes x < x_L + m t²/2 + "
        "c0 t + 1 m, where the upstream wall's rarefaction has arrived."),
    "voellmy_sheet": (
        "Reference (`fem_runout/references/voellmy_sheet.py`; Voellmy 1955): a uniform 1 m "
        "layer released on Z = −0.3 x with μ = 0.1, ξ = 500 m/s²; du/dt = g (S − μ) − "
        "g u²/(ξ h), so u = sqrt(a/b) tanh(sqrt(a b) t), a = g (S − μ), b = g/(ξ h), terminal "
        "speed sqrt(ξ h (S − μ)) = 10 m/s. Measured at 3 relaxation times (u = 0.995 u_∞) on "
        "the part of the 400 m strip that the boundaries have not yet reached. The solution is "
        "uniform in space: this measures the time integration (the step is ∝ dx)."),
    "shear_decay": (
        "Reference (`fem_runout/references/shear_decay.py`): with τ_Y = 0 the Bingham stress "
        "is Newtonian and a shear flow u = U cos(k y), v = 0 on a flat bed with uniform depth "
        "obeys ∂t u = (μ/ρ) ∂yy u, so it decays as exp(−μ k² t/ρ); μ = 500 Pa s, ρ = 1000 "
        "kg/m³, k = 2π/10 m⁻¹, slip walls at y = 0, 10 m; rate fitted on 10 ≤ x ≤ 30 m."),
    "inclined_dam_break": (
        "Reference (`fem_runout/references/inclined_dam_break.py`, seed §4.1): the exact "
        "dry-bed tip on Z = 100 − x/3 is x0 + 2 sqrt(g h0) t + g S t²/2 with h0 = 20/3 m at "
        "x0 = 20 m, S = 1/3 (76.8, 158.4, 264.7, 395.7 m at 2.75, 5.5, 8.25, 11 s). Domain "
        "[0, 450] × [0, 20] m (the same flow as the seed's [0, 300] until the front reaches "
        "300 m), open boundaries; front = largest x with h > 1e-3 m."),
    "hemisphere": (
        "Reference: symmetry (seed §4.1.1). h = sqrt(25 − |x − (25, 25)|²) on [0, 50]², flat, "
        "frictionless, open, t = 1.2 s; the exact flow is radially symmetric, so the front "
        "radius (h > 1e-3 m) along x, y, −x and the diagonal must agree; one cell along the "
        "diagonal is sqrt(2) dx. The seed reports a diameter of about 13 m at 1.2 s."),
    "lake_at_rest": (
        "Reference: the still state h + Z = 10 m, v = 0 (seed §4.2, eq. 47–48) over three "
        "Gaussian bumps, two of them emerging (dry), with the seed's full material (Voellmy "
        "φ = 26°, ξ = 500 m/s²; Bingham μ = 2000 Pa s, τ_Y = 30 Pa; ρ = 1200 kg/m³), walls, "
        "T = 1 s; must stay exact."),
}

READING = "## Reading\n\n(filled in after the run)"
