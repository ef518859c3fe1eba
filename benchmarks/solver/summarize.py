#!/usr/bin/env python3
"""Summary step of benchmarks/solver/run.sh (standard library + gnuplot only).

Reads the trace CSVs of one run.sh mode, writes results/<mode>/traces.csv,
draws plots/<mode>_<axis>.png (CD and F@2 % against solve seconds, one line
per configuration) and rewrites the mode's block in benchmarks/README.md,
between <!-- BEGIN solver-tables --> and <!-- END solver-tables --> (full
mode) or the same markers with a "-quick" suffix (quick mode, appended when
absent, so a smoke run never overwrites the full run's tables): Pareto table,
the step-rule time ratio and the stability table. README.md in this folder
explains the columns.
"""
import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile

CERES_RULES = ["lm", "lm_schur", "alternate"]


def markers(mode):
    """The (BEGIN, END) comment pair that delimits mode's README block."""
    suffix = "" if mode == "full" else f"-{mode}"
    return f"<!-- BEGIN solver-tables{suffix} -->", f"<!-- END solver-tables{suffix} -->"


def num(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return float("nan")


def legacy_names(row):
    """A trace row with the column names of today: traces written before
    2026-11-26 call the batch index `iteration`."""
    if "iteration" in row and "batch" not in row:
        row = {("batch" if k == "iteration" else k): v for k, v in row.items()}
    return row


def read_runs(work, group):
    """{name: {"rows": [...], "done": {...} or None}} of work/group/*/."""
    runs = {}
    gdir = os.path.join(work, group)
    if not os.path.isdir(gdir):
        return runs
    for name in sorted(os.listdir(gdir)):
        path = os.path.join(gdir, name, "trace.csv")
        if not os.path.isfile(path):
            continue
        with open(path, newline="") as f:
            rows = [legacy_names(r) for r in csv.DictReader(f)]
        done = None
        done_path = os.path.join(gdir, name, "done")
        if os.path.isfile(done_path):
            done = {}
            with open(done_path) as f:
                for line in f:
                    k, _, v = line.partition(" ")
                    done[k] = v.strip()
        runs[name] = {"rows": rows, "done": done, "group": group}
    return runs


def write_done_csv(res_dir, groups):
    """results/<mode>/done.csv: the done file of every finished run (group,
    config, key, value), so that a later run.sh --resume can restore them."""
    tmp = os.path.join(res_dir, "done.csv.tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["group", "config", "key", "value"])
        for group_runs in groups:
            for name, run in group_runs.items():
                for k, v in (run["done"] or {}).items():
                    w.writerow([run["group"], name, k, v])
    os.replace(tmp, os.path.join(res_dir, "done.csv"))


def restore(work, res_dir):
    """Recreates work/<group>/<config>/{trace.csv,done} of every run that
    results/<mode>/done.csv lists as finished and that work/ does not hold:
    run.sh --resume then keeps them, so a long run can span machines or
    sessions through the committed CSVs. Returns the restored names."""
    traces = os.path.join(res_dir, "traces.csv")
    dones = os.path.join(res_dir, "done.csv")
    if not (os.path.isfile(traces) and os.path.isfile(dones)):
        return []
    done = {}
    with open(dones, newline="") as f:
        for r in csv.DictReader(f):
            done.setdefault((r["group"], r["config"]), []).append((r["key"], r["value"]))
    with open(traces, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = {}
        for r in reader:
            rows.setdefault((r[0], r[1]), []).append(r[1:])
    restored = []
    for (group, name), kv in sorted(done.items()):
        out = os.path.join(work, group, name)
        if os.path.isfile(os.path.join(out, "done")) or (group, name) not in rows:
            continue
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, "trace.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(header[1:])
            w.writerows(rows[(group, name)])
        with open(os.path.join(out, "done"), "w") as f:
            for k, v in kv:
                f.write(f"{k} {v}\n")
        with open(os.path.join(out, "log.txt"), "w") as f:
            f.write(f"restored from {traces}\n")
        restored.append(f"{group}/{name}")
    return restored


def trace_rows(run):
    return [r for r in run["rows"] if r["kind"] == "trace"]


def final_trace(run):
    rows = trace_rows(run)
    return rows[-1] if rows else None


def final_full(run):
    rows = [r for r in run["rows"] if r["kind"] == "final"]
    return rows[-1] if rows else None


def no_surface(row):
    """True when the row's extracted mesh is empty: the SDF has no zero level
    set (a collapse, not a numerical failure, so it needs its own flag)."""
    return row is not None and num(row["mesh_vertices"]) == 0


def nonfinite_row(run):
    rows = [r for r in run["rows"] if r["kind"] == "nonfinite"]
    return rows[0] if rows else None


def read_axes(path, mode):
    axes = {}  # axis -> [config names in file order]
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            modes, axis_list, name = parts[0], parts[1], parts[2]
            if modes not in ("all", mode):
                continue
            for axis in axis_list.split(","):
                axes.setdefault(axis, []).append(name)
    return axes


def pareto(points, better):
    """Names of the non-dominated (time, value) points; better(a, b): a at least as good."""
    out = set()
    for name, (t, v) in points.items():
        if math.isnan(v):
            continue
        dominated = False
        for other, (t2, v2) in points.items():
            if other == name or math.isnan(v2):
                continue
            if t2 <= t and better(v2, v) and (t2 < t or v2 != v):
                dominated = True
                break
        if not dominated:
            out.add(name)
    return out


def fmt(v, digits=2):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "n/a"
    return f"{v:.{digits}f}"


def time_to_reach(run, target):
    """First trace row with F@2 >= target: (solve_seconds, batches) or None."""
    for r in trace_rows(run):
        if num(r["fscore_2"]) >= target:
            return num(r["solve_seconds"]), int(r["total_batches"])
    return None


def plot_axis(results, mode, axis, names, runs, tmp, readme_dir, scene="the comparison scene"):
    files = []
    for name in names:
        if name not in runs:
            continue
        path = os.path.join(tmp, f"{axis}_{name}.dat")
        with open(path, "w") as f:
            for r in trace_rows(runs[name]):
                cd = num(r["chamfer_cm"])
                if math.isnan(cd):
                    continue
                f.write(f"{num(r['solve_seconds'])} {cd} {num(r['fscore_2'])}\n")
        files.append((name, path))
    if not files:
        return None
    def title(n):
        return n + " (base config)" if n == "adam" else n

    png = os.path.join(results, "plots", f"{mode}_{axis}.png")
    os.makedirs(os.path.dirname(png), exist_ok=True)
    label = "QUICK SMOKE RUN (tiny budgets, not a result)" if mode == "quick" else "full run"
    script = [
        "set terminal pngcairo noenhanced size 1200,480 font ',10'",
        f"set output '{png}.tmp'",
        "set multiplot layout 1,2 title "
        f"'{axis}: speed against error on {scene} ({label})'",
        "set grid",
        "set key outside bottom center horizontal",
        "set xlabel 'solve seconds (without trace evaluations)'",
        "set ylabel 'Chamfer distance (cm, banmo protocol, trace resolution)'",
        "plot " + ", ".join(f"'{p}' using 1:2 with linespoints title '{title(n)}'" for n, p in files),
        "set ylabel 'F@2% (percent)'",
        "plot " + ", ".join(f"'{p}' using 1:3 with linespoints title '{title(n)}'" for n, p in files),
        "unset multiplot",
    ]
    subprocess.run(["gnuplot"], input="\n".join(script), text=True, check=True)
    os.replace(png + ".tmp", png)
    return os.path.relpath(png, readme_dir)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mode", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--results", required=True, help="folder of plots/ and results/")
    ap.add_argument("--restore", action="store_true",
                    help="only restore finished runs from results/<mode>/ into --work")
    ap.add_argument("--here")
    ap.add_argument("--readme")
    ap.add_argument("--run-seconds", type=float)
    ap.add_argument("--command")
    ap.add_argument("--setup", default="",
                    help="base config, budget and threads of the runs, printed under the command")
    a = ap.parse_args()
    if a.restore:
        names = restore(a.work, os.path.join(a.results, "results", a.mode))
        for n in names:
            print(f"[restore] {n}: finished in an earlier run (results/{a.mode}/traces.csv)")
        return
    for req in ("here", "readme", "run_seconds", "command"):
        if getattr(a, req) is None:
            ap.error(f"--{req.replace('_', '-')} is required")

    compare = read_runs(a.work, "compare")
    stability = read_runs(a.work, "stability")
    fox = read_runs(a.work, "fox")
    axes = read_axes(os.path.join(a.here, "configs.txt"), a.mode)

    # Combined CSV.
    res_dir = os.path.join(a.results, "results", a.mode)
    os.makedirs(res_dir, exist_ok=True)
    header = None
    lines = []
    for group_runs in (compare, stability, fox):
        for name, run in group_runs.items():
            for r in run["rows"]:
                if header is None:
                    header = ["group"] + list(r.keys())
                lines.append([run["group"]] + [r[k] for k in header[1:]])
    if header:
        tmp_csv = os.path.join(res_dir, "traces.csv.tmp")
        with open(tmp_csv, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(header)
            w.writerows(lines)
        os.replace(tmp_csv, os.path.join(res_dir, "traces.csv"))
        write_done_csv(res_dir, (compare, stability, fox))

    # Plots.
    plots = []
    with tempfile.TemporaryDirectory() as tmp:
        for axis, names in axes.items():
            p = plot_axis(a.results, a.mode, axis, names, compare, tmp,
                          os.path.dirname(os.path.abspath(a.readme)))
            if p:
                plots.append((axis, p))
        # The Fox step rules (--fox): one more plot, on their own scene.
        p = plot_axis(a.results, a.mode, "fox_step_rule",
                      [f"fox_{r}" for r in ("adam", "lm", "alternate")], fox, tmp,
                      os.path.dirname(os.path.abspath(a.readme)), "the Fox (30-minute budget)")
        if p:
            plots.append(("fox_step_rule", p))

    out = []
    quick = a.mode == "quick"
    begin, end = markers(a.mode)
    out.append(begin)
    out.append("<!-- generated by benchmarks/solver/run.sh (summarize.py); edits here are lost -->")
    title = "QUICK SMOKE RUN: tiny scene and budgets, proves the pipeline, NOT a result" if quick \
        else "full run"
    out.append(f"### Solver comparisons and stability ({title})")
    out.append("")
    out.append(f"Command: `{a.command}`; run time {a.run_seconds / 60:.1f} min "
               f"(build, scenes, runs; wall clock, other jobs on the machine may have been "
               f"running). CSV: `benchmarks/solver/results/{a.mode}/traces.csv`. "
               "Columns and method: benchmarks/solver/README.md.")
    if a.setup:
        out.append("")
        out.append(f"Runs of this part: {a.setup}. Rows restored from earlier parts were "
                   f"measured as their own parts said (`results/{a.mode}/done.csv`).")
    out.append("")

    # Pareto table over the final trace point of each configuration.
    finals = {n: final_trace(r) for n, r in compare.items() if final_trace(r)}
    pts_cd = {n: (num(r["solve_seconds"]), num(r["chamfer_cm"])) for n, r in finals.items()}
    pts_f2 = {n: (num(r["solve_seconds"]), num(r["fscore_2"])) for n, r in finals.items()}
    par_cd = pareto(pts_cd, lambda x, y: x <= y)
    par_f2 = pareto(pts_f2, lambda x, y: x >= y)
    if finals:
        scene = next(iter(finals.values()))["scene"]
        out.append(f"Configurations on scene `{scene}`, final trace point (trace resolution, "
                   "frame subset); **P** = on the Pareto front of (solve time, CD) or "
                   "(solve time, F@2). Full-resolution CD: all frames at the final resolution "
                   "(full mode only).")
        out.append("")
        out.append("| config | axes | batches | solve s | CPU s | CD cm | F@1 | F@2 | F@5 | "
                   "Pareto CD | Pareto F@2 | CD full-res | F@2 full-res |")
        out.append("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | :---: | :---: "
                   "| ---: | ---: |")
        axis_of = {}
        for axis, names in axes.items():
            for n in names:
                axis_of.setdefault(n, []).append(axis)
        for n in sorted(finals, key=lambda k: num(finals[k]["solve_seconds"])):
            r = finals[n]
            full = final_full(compare[n])
            bad = nonfinite_row(compare[n])
            name = n + (" (NON-FINITE)" if bad else "") + \
                (" (NO SURFACE)" if no_surface(full or r) else "")
            out.append(
                f"| {name} | {', '.join(axis_of.get(n, []))} | {r['total_batches']} | "
                f"{fmt(num(r['solve_seconds']), 1)} | {fmt(num(r['cpu_seconds']), 1)} | "
                f"{fmt(num(r['chamfer_cm']))} | {fmt(num(r['fscore_1']), 1)} | "
                f"{fmt(num(r['fscore_2']), 1)} | {fmt(num(r['fscore_5']), 1)} | "
                f"{'P' if n in par_cd else ''} | {'P' if n in par_f2 else ''} | "
                f"{fmt(num(full['chamfer_cm'])) if full else 'n/a'} | "
                f"{fmt(num(full['fscore_2']), 1) if full else 'n/a'} |")
        out.append("")

    # Step-rule ratio: time of the best Ceres rule to reach Adam's final F@2.
    def ratio_text(runs, adam_name, rules, label):
        if adam_name not in runs or not final_trace(runs[adam_name]):
            return None
        adam = final_trace(runs[adam_name])
        target = num(adam["fscore_2"])
        t_adam = num(adam["solve_seconds"])
        best = None
        parts = []
        unreached_seconds = []  # the whole solve time of each rule that missed the target
        for rule in rules:
            if rule not in runs:
                continue
            hit = time_to_reach(runs[rule], target)
            if hit:
                parts.append(f"{rule} {hit[0]:.1f} s ({hit[1]} batches)")
                if best is None or hit[0] < best[1]:
                    best = (rule, hit[0])
            else:
                seconds = num(final_trace(runs[rule])["solve_seconds"])
                unreached_seconds.append(seconds)
                parts.append(f"{rule} not reached (best F@2 "
                             f"{max(num(x['fscore_2']) for x in trace_rows(runs[rule])):.1f} in "
                             f"{seconds:.1f} s)")
        text = (f"{label}: Adam's final F@2 = {target:.1f} % after {t_adam:.1f} s; time to "
                f"reach it: {'; '.join(parts) if parts else 'no Ceres runs'}.")
        # Adam may pass its final F@2 long before its end (a plateau, or a
        # noisy trace): the ratio against that first time is the stricter one.
        adam_first = time_to_reach(runs[adam_name], target)
        if best:
            text += (f" **Ratio best Ceres rule ({best[0]}) / Adam = "
                     f"{best[1] / t_adam:.2f}** (first trace point at or above the target, so "
                     "the Ceres time is rounded up to the trace schedule).")
            if adam_first and adam_first[0] < t_adam:
                text += (f" Adam itself first reached the target after {adam_first[0]:.1f} s "
                         f"({adam_first[1]} batches): against that time the ratio is "
                         f"{best[1] / adam_first[0]:.2f}.")
        elif unreached_seconds:
            # None reached the target: each rule would need more than its whole
            # run, so the shortest Ceres run bounds the ratio from below.
            bound = min(unreached_seconds) / t_adam
            text += (f" **Ratio best Ceres rule / Adam > {bound:.2f}** (a lower bound: no "
                     "Ceres rule reached the target within its budget).")
            if adam_first and adam_first[0] < t_adam:
                text += (f" Adam itself first reached the target after {adam_first[0]:.1f} s "
                         f"({adam_first[1]} batches): against that time the bound is "
                         f"> {min(unreached_seconds) / adam_first[0]:.2f}.")
        return text

    t = ratio_text(compare, "adam", CERES_RULES, "Comparison scene")
    if t:
        out.append(t)
        out.append("")
    t = ratio_text({k.replace("fox_", ""): v for k, v in fox.items()}, "adam", ["lm", "alternate"],
                   "Fox, 30-minute budget")
    if t:
        out.append(t)
        out.append("")

    if plots:
        out.append("Plots (CD and F@2 against solve seconds, one line per configuration):")
        out.append("")
        for axis, p in plots:
            out.append(f"- {axis}: [{p}]({p})")
        out.append("")

    # Stability table.
    if stability:
        out.append("Stability suite (stability.txt; every run must end without NaN/Inf; "
                   "surface: whether the final mesh has any vertices):")
        out.append("")
        out.append("| case | scene | overrides | batches | solve s | finite | surface | CD cm | "
                   "F@2 | CD full-res | F@2 full-res |")
        out.append("| --- | --- | --- | ---: | ---: | --- | --- | ---: | ---: | ---: | ---: |")
        overrides = {}
        with open(os.path.join(a.here, "stability.txt")) as f:
            for line in f:
                parts = line.split()
                if parts and not parts[0].startswith("#") and parts[0] in ("all", a.mode):
                    overrides[parts[1]] = " ".join(parts[3:])
        for n, run in stability.items():
            r = final_trace(run)
            bad = nonfinite_row(run)
            full = final_full(run)
            last = bad or r
            if last is None:
                continue
            if bad:
                finite = (f"**NO**: stage {bad['stage']} ({bad['stage_name']}) batch "
                          f"{bad['batch']}, {bad['nonfinite_what']}")
            elif run["done"] is None:
                finite = "**run did not finish** (see log.txt)"
            else:
                finite = "yes"
            surface = "n/a" if bad else ("**none**" if no_surface(full or r) else "yes")
            ov = overrides.get(n, "")
            out.append(
                f"| {n} | {last['scene']} | {('`' + ov + '`') if ov else ''} | "
                f"{last['total_batches']} | {fmt(num(last['solve_seconds']), 1)} | {finite} | "
                f"{surface} | {fmt(num(r['chamfer_cm'])) if r and not bad else 'n/a'} | "
                f"{fmt(num(r['fscore_2']), 1) if r and not bad else 'n/a'} | "
                f"{fmt(num(full['chamfer_cm'])) if full else 'n/a'} | "
                f"{fmt(num(full['fscore_2']), 1) if full else 'n/a'} |")
        out.append("")
    out.append(end)
    block = "\n".join(out)

    with open(a.readme) as f:
        text = f.read()
    if begin in text and end in text:
        pre = text[: text.index(begin)]
        post = text[text.index(end) + len(end):]
        text = pre + block + post
    else:
        heading = "Quick smoke run of the solver harness" if quick else \
            "Solver comparisons and stability"
        command = "bash benchmarks/solver/run.sh" + (" --quick" if quick else "")
        text = text.rstrip("\n") + f"\n\n## {heading}\n\n" + \
            f"Generated by `{command}` (benchmarks/solver/README.md).\n\n" + block + "\n"
    tmp = a.readme + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, a.readme)
    print(block)


if __name__ == "__main__":
    sys.exit(main())
