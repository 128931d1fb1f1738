"""The benchmark's figures: work-precision per scene and scaling."""
from tslib import plots
from tslib.bench.config import INTEGRATOR_STYLE, SCENES


def plot_work_precision(rows, names, out_dir):
    """Per scene: headline error (left) and exit-velocity error (right) against cost."""
    plt = plots.pyplot()
    paths = []
    for name in names:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
        for ax, metric, ylabel in ((axes[0], "headline", "headline error (largest of four) [-]"),
                                   (axes[1], "exit_velocity", "exit velocity error [-]")):
            for integrator, (color, style) in INTEGRATOR_STYLE.items():
                # In knob order (coarse to fine), so that the line follows the sweep.
                pts = [(r["wall_per_sim_s"], r[metric], r["knob"]) for r in
                       sorted((r for r in rows if r["scene"] == name and
                               r["integrator"] == integrator), key=lambda r: -r["knob"])]
                pts = [p for p in pts if p[1] > 0]
                if not pts:
                    continue
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, color=color,
                          label=integrator.replace("_", "-") +
                          (" (tolerance)" if integrator == "event_driven" else " (dt)"))
                for x, y, knob in pts:
                    ax.annotate(f"{knob:g}", (x, y), textcoords="offset points", xytext=(4, 3),
                                fontsize=7, color=color)
            # Real time and 20x faster than real time.
            for x, text, ls in ((1.0, "real time", ":"), (0.05, "20x", "-.")):
                ax.axvline(x, color="gray", lw=0.8, ls=ls)
                ax.text(x, ax.get_ylim()[0], " " + text, va="bottom", fontsize=7, color="gray")
            ax.set_xlabel("wall time per simulated second [s/s]")
            ax.set_ylabel(ylabel)
            ax.grid(True, which="both", lw=0.3)
            ax.legend(fontsize=8, loc="lower left" if metric == "exit_velocity" else "best")
        fig.suptitle(SCENES[name][2], fontsize=10)
        fig.tight_layout()
        path = out_dir / f"wp_{name}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths


def plot_scaling(rows, out_dir):
    plt = plots.pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for integrator, (color, style) in INTEGRATOR_STYLE.items():
        for series, ls in (("kernels", "-"), ("idle kernels", ":")):
            pts = sorted((r["n"], r["wall_per_sim_s"], r["completed"]) for r in rows
                         if r["series"] == series and r["integrator"] == integrator)
            if pts:
                axes[0].loglog([p[0] for p in pts], [p[1] for p in pts], style[0], ls=ls,
                               color=color, label=f"{integrator.replace('_', '-')}, {series}")
                for n, c, done in pts:
                    if not done:
                        axes[0].annotate("cut short", (n, c), textcoords="offset points",
                                         xytext=(-40, 6), fontsize=7, color=color)
        pts = sorted((r["n"] + 1, r["wall_per_sim_s"]) for r in rows
                     if r["series"] == "modes" and r["integrator"] == integrator)
        axes[1].loglog([p[0] for p in pts], [p[1] for p in pts], style, color=color,
                       label=integrator.replace("_", "-"))
    axes[0].set_xlabel("kernels (stream scene; idle: every kernel out of reach)")
    axes[1].set_xlabel("tooth modes + 1 (single strike)")
    for ax in axes:
        ax.set_ylabel("wall time per simulated second [s/s]")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    path = out_dir / "scaling.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
