"""Console table and markdown of a :class:`~urident.gap.results.GapResult` (its JSON:
:func:`urident.gap.results.result_dict`)."""

from __future__ import annotations


def format_report(res, top: int = 12) -> str:
    lines = []
    b, f = res.baseline_rms, res.final_rms
    summary = getattr(res.model, "summary", None)  # a simulator model describes itself
    baseline = summary() if summary else f"{res.model.method.upper()} ({res.model.model.friction_summary()})"
    lines.append(f"Sim-to-real gap, robot {res.robot}: baseline {baseline}, "
                 f"{res.ident.n} identification / {res.valid.n} validation samples")
    lines.append("")
    lines.append("Where (validation residual, measured - predicted):")
    lines.append("  joint   RMS [Nm]   share   bias [Nm]")
    for jd in res.where["joints"]:
        lines.append(f"  {jd['joint']:5d}  {jd['rms_nm']:9.3f}  {100 * jd['energy_share']:5.1f} %  "
                     f"{jd['mean_nm']:+9.3f}")
    for jd in res.where["joints"]:
        for text in jd["regimes"]:
            lines.append(f"  - {text}")
    events = getattr(res, "events", [])
    if events:
        aside = sum(e.stop - e.start for e in events)
        lines.append(f"  Events (time-localised, no smooth effect: set aside, {aside} of "
                     f"{res.n_valid_all or res.valid.n} samples):")
        for e in events:
            js = ", ".join(f"{j + 1} (peak {p:+.1f}, RMS {r:.1f} N·m)"
                           for j, p, r in zip(e.joints, e.peak_nm, e.rms_nm))
            lines.append(f"    {e.kind} t = {e.t_start_s:.2f}-{e.t_end_s:.2f} s: joints {js}")
    ref = res.where.get("controller_model")
    if ref:
        fmt = lambda xs: " ".join(f"{x:7.3f}" for x in xs)   # noqa: E731
        lines.append("  Logged target moment (the controller's model for the target motion), RMS per joint [Nm]:")
        lines.append(f"    target moment                       {fmt(ref['target_rms_nm'])}")
        lines.append(f"    measured - target moment            {fmt(ref['measured_minus_target_rms_nm'])}")
        lines.append(f"    identified rigid body - target      {fmt(ref['rigid_body_minus_target_rms_nm'])}")
        scale = " ".join("      -" if x is None else f"{x:7.3f}" for x in ref["measured_over_target_scale"])
        lines.append(f"    measured / target (LS scale)        {scale}")
        ch = ref.get("change_between_runs")
        if ch:
            verdict = ("changed between the runs: a payload or tool declared to the controller"
                       if ch["changed"] else "unchanged between the runs (no payload declared in between)")
            lines.append(f"    controller model, ident -> valid    {fmt(ch['rms_nm'])}  {verdict}")
    lines.append("")
    lines.append("Which (first step: each candidate added alone; held-out gain, 95 % interval):")
    lines.append("  effect                 joint  mode   variant                    gain [Nm^2]"
                 "      95 % interval         shrink")
    for s in (res.steps[0] if res.steps else [])[:top]:
        c = s.candidate
        mark = "*" if s.significant else " "
        lines.append(f" {mark}{c.effect:22s} {s.joint + 1:5d}  {c.mode:5s}  {c.variant[:24]:24s}  "
                     f"{s.gain:11.4g}  [{s.ci[0]:9.3g}, {s.ci[1]:9.3g}]  {s.shrink_pct:5.1f} %")
    lines.append("  (* significant: lower bound > 0 and shrink >= "
                 f"{res.config.min_shrink_pct:g} % of the joint's RMS; CV mode also a correction "
                 f"RMS >= {res.config.cv_min_noise_ratio:g} x the joint's white-noise torque)")
    lines.append("")
    if not res.findings:
        lines.append("Findings: no unmodelled effect found")
    else:
        lines.append("Findings (stepwise selection: forward, then backward):")
        for k, x in enumerate(res.findings):
            mag = ", ".join(f"{key} = {_fmt(v)}" for key, v in x.magnitude.items() if key != "coefficients")
            where = f"joint {x.joint}"
            if len(x.joints) > 1:     # an effect on all joints: each joint with the torque it explains
                where = "joints " + ", ".join(f"{jj} ({t:.3g} N·m RMS)" for jj, t in zip(x.joints, x.torque_nm))
            lines.append(f"  {k + 1}. {x.effect} on {where} [{x.mode}] {x.variant}: "
                         f"RMS {x.rms_before_nm:.3f} -> {x.rms_after_nm:.3f} N·m "
                         f"({x.shrink_pct:.1f} % smaller), confidence {x.confidence}")
            lines.append(f"     where: {x.regime}")
            if x.claim == "partial":
                lines.append(f"     PARTIAL explanation, not the cause: {x.remains['text']}")
            if mag:
                lines.append(f"     fitted: {mag}")
            if x.confounded_with:
                lines.append(f"     confounded with: {'; '.join(x.confounded_with)} "
                             "(the data cannot tell them apart)")
    left = res.where.get("unexplained") or []
    if left:
        lines.append("")
        lines.append("Beyond the catalogue (residual left after the findings: above the noise or structured):")
        for u in left:
            lines.append(f"  joint {u['joint']}: RMS {u['rms_nm']:.3f} N·m, {u['noise_ratio']:.1f} x its "
                         f"white-noise torque ({u['noise_nm']:.3f} N·m); structured part "
                         f"{u['structured_rms_nm']:.3f} N·m")
            for st in u.get("structure", [])[:3]:     # the JSON has them all
                lines.append(f"     structure: {st['text']}")
            for text in u["regimes"] or ["spread over all regimes"]:
                lines.append(f"     where: {text}")
    lines.append("")
    lines.append("How far (validation):")
    lines.append("  joint   baseline [Nm]   final [Nm]   shrink")
    for j in range(6):
        sh = 100 * (1 - f[j] / b[j]) if b[j] > 0 else 0.0
        lines.append(f"  {j + 1:5d}  {b[j]:13.3f}  {f[j]:11.3f}  {sh:5.1f} %")
    en_sh = 100 * (1 - res.final_e_n / res.baseline_e_n) if res.baseline_e_n > 0 else 0.0
    lines.append(f"  e_N    {res.baseline_e_n:13.4g}  {res.final_e_n:11.4g}  {en_sh:5.1f} %")
    return "\n".join(lines)


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def maps_markdown(res) -> str:
    """The findings and the residual maps as markdown (for a Rerun text view)."""
    lines = ["# Sim-to-real gap", "", f"**Verdict:** {res.verdict}", ""]
    for x in res.findings:
        lines.append(f"- **{x.effect}** on joint {x.joint}: RMS {x.rms_before_nm:.3f} → "
                     f"{x.rms_after_nm:.3f} N·m ({x.shrink_pct:.1f} %), {x.confidence}; {x.regime}")
    lines.append("")
    for jd in res.where["joints"]:
        lines += [f"## Joint {jd['joint']}: RMS {jd['rms_nm']:.3f} N·m, "
                  f"{100 * jd['energy_share']:.1f} % of the residual energy", ""]
        for text in jd["regimes"]:
            lines.append(f"- {text}")
        for axis, bins in jd["maps"].items():
            lines += ["", f"**{axis}**", "", "| bin | samples | energy | RMS [N·m] | mean [N·m] |",
                      "| --- | ---: | ---: | ---: | ---: |"]
            for b in bins:
                rms = "-" if b["rms_nm"] is None else f"{b['rms_nm']:.3f}"
                mean = "-" if b["mean_nm"] is None else f"{b['mean_nm']:+.3f}"
                lines.append(f"| {b['label']} | {100 * b['sample_share']:.0f} % | "
                             f"{100 * b['energy_share']:.0f} % | {rms} | {mean} |")
        sp = jd["angle_spectrum"]
        peaks = ", ".join(f"k={p['k']}: {p['amplitude_nm']:.3f}" for p in sp["peaks"])
        fr = jd["frequency"]
        lines += ["", f"Angle spectrum peaks [N·m]: {peaks}",
                  f"Residual vs dτ̂/dt correlation {fr['corr_dtau']:+.2f} (delay {1000 * fr['delay_s']:.1f} ms)", ""]
    return "\n".join(lines)


def logs_used(recordings, title: str) -> str:
    """Which logs (rows, samples, sha256, torque signal) a diagnosis used, a line each."""
    from urident.ident.preprocess import file_sha256
    from urident.ident.torque import describe_signal

    lines = [f"{title} ({len(recordings)}):"]
    for rec in recordings:
        rows = (rec.metadata or {}).get("rows")
        rows = "" if rows is None else f" rows {rows[0]}-{rows[1]},"
        lines.append(f"  {rec.source}:{rows} {len(rec.t)} samples, sha256 {file_sha256(rec.source) or '-'}; "
                     f"{describe_signal(rec)}")
    return "\n".join(lines)
