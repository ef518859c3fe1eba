#!/usr/bin/env python3
"""ctest summarize_test: summarize.py writes results/<mode>/{traces,done}.csv
and the README block, and --restore rebuilds the finished runs from them (the
cross-session --resume of run.sh). Standard library + gnuplot only."""
import csv
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SUMMARIZE = os.path.join(HERE, "summarize.py")
COLUMNS = ["config", "scene", "kind", "stage", "stage_name", "batch", "total_batches",
           "solve_seconds", "cpu_seconds", "wall_seconds", "trace_seconds", "loss_total",
           "loss_rgb", "loss_silhouette", "loss_flow", "loss_feature_match", "loss_cycle_2d",
           "loss_cycle_3d", "params_finite", "losses_finite", "nonfinite_what", "resolution",
           "mesh_vertices", "eval_frames", "chamfer_cm", "fscore_1", "fscore_2", "fscore_5"]


def write_run(work, group, name, scene, points, done, vertices=100, legacy=False):
    """legacy: the header of traces written before 2026-11-26 (`iteration`
    for `batch`)."""
    d = os.path.join(work, group, name)
    os.makedirs(d)
    with open(os.path.join(d, "trace.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS)
        if legacy:
            f.write(",".join("iteration" if c == "batch" else c for c in COLUMNS) + "\n")
        else:
            w.writeheader()
        for i, (sec, cd) in enumerate(points):
            row = {c: "0" for c in COLUMNS}
            row.update(config=name, scene=scene, kind="trace", stage=str(0 if i else -1),
                       stage_name="all" if i else "", batch=str(10 * i),
                       total_batches=str(10 * i), solve_seconds=str(sec), params_finite="1",
                       losses_finite="1", nonfinite_what="", mesh_vertices=str(vertices),
                       chamfer_cm=str(cd),
                       fscore_2=str(100 - cd))
            w.writerow(row)
    if done:
        with open(os.path.join(d, "done"), "w") as f:
            f.write(f"batches {10 * (len(points) - 1)}\nsolve_seconds {points[-1][0]}\n")


ADAM_LM_CONFIGS = "all step_rule adam\nall step_rule lm stages[*].step_rule=lm\n"
NOISE50_STABILITY = "all noise50 quad_n\n"


def write_tables(tmp, configs, stability):
    """tmp/here/{configs,stability}.txt and a README with the empty block;
    returns (here, readme)."""
    here = os.path.join(tmp, "here")
    os.makedirs(here)
    with open(os.path.join(here, "configs.txt"), "w") as f:
        f.write(configs)
    with open(os.path.join(here, "stability.txt"), "w") as f:
        f.write(stability)
    readme = os.path.join(tmp, "README.md")
    with open(readme, "w") as f:
        f.write("# x\n<!-- BEGIN solver-tables -->\n<!-- END solver-tables -->\n")
    return here, readme


class RestoreTest(unittest.TestCase):
    def run_summarize(self, *args):
        subprocess.run([sys.executable, SUMMARIZE, *args], check=True,
                       stdout=subprocess.DEVNULL)

    def test_round_trip(self):
        with tempfile.TemporaryDirectory() as tmp:
            work, res = os.path.join(tmp, "work"), os.path.join(tmp, "res")
            here, readme = write_tables(tmp, ADAM_LM_CONFIGS, NOISE50_STABILITY)
            write_run(work, "compare", "adam", "quad", [(0, 30), (5, 20), (10, 15)], True)
            write_run(work, "compare", "lm", "quad", [(0, 30), (8, 14)], True)
            write_run(work, "stability", "noise50", "quad_n", [(0, 30), (4, 25)], False)
            self.run_summarize("--mode", "full", "--work", work, "--here", here,
                               "--results", res, "--readme", readme, "--run-seconds", "1",
                               "--command", "test")
            traces = os.path.join(res, "results", "full", "traces.csv")
            with open(os.path.join(res, "results", "full", "done.csv")) as f:
                done_rows = list(csv.DictReader(f))
            self.assertEqual({(r["group"], r["config"]) for r in done_rows},
                             {("compare", "adam"), ("compare", "lm")})

            # Restore into an empty work dir: the finished runs only, same rows.
            work2 = os.path.join(tmp, "work2")
            self.run_summarize("--restore", "--mode", "full", "--work", work2, "--results", res)
            for name in ("adam", "lm"):
                for fname in ("trace.csv", "done"):
                    with open(os.path.join(work, "compare", name, fname)) as a, \
                            open(os.path.join(work2, "compare", name, fname)) as b:
                        self.assertEqual(a.read(), b.read(), f"{name}/{fname}")
            self.assertFalse(os.path.exists(os.path.join(work2, "stability", "noise50")),
                             "an unfinished run must not come back as finished")

            # Summarising the restored runs gives the same combined CSV (minus
            # the unfinished run), and a second restore changes nothing.
            with open(traces) as f:
                before = [l for l in f if not l.startswith("stability,")]
            res2 = os.path.join(tmp, "res2")
            self.run_summarize("--mode", "full", "--work", work2, "--here", here,
                               "--results", res2, "--readme", readme, "--run-seconds", "1",
                               "--command", "test")
            with open(os.path.join(res2, "results", "full", "traces.csv")) as f:
                self.assertEqual(before, f.readlines())
            out = subprocess.run([sys.executable, SUMMARIZE, "--restore", "--mode", "full",
                                  "--work", work2, "--results", res], check=True,
                                 capture_output=True, text=True).stdout
            self.assertEqual(out, "")

    def test_traces_of_the_old_column_name_mix_with_new_ones(self):
        with tempfile.TemporaryDirectory() as tmp:
            work, res = os.path.join(tmp, "work"), os.path.join(tmp, "res")
            here, readme = write_tables(tmp, ADAM_LM_CONFIGS, NOISE50_STABILITY)
            write_run(work, "compare", "adam", "quad", [(0, 30), (5, 20)], True, legacy=True)
            write_run(work, "compare", "lm", "quad", [(0, 30), (8, 14)], True)
            self.run_summarize("--mode", "full", "--work", work, "--here", here,
                               "--results", res, "--readme", readme, "--run-seconds", "1",
                               "--command", "test")
            with open(os.path.join(res, "results", "full", "traces.csv"), newline="") as f:
                rows = list(csv.DictReader(f))
            self.assertNotIn("iteration", rows[0])
            self.assertEqual({(r["config"], r["batch"]) for r in rows},
                             {("adam", "0"), ("adam", "10"), ("lm", "0"), ("lm", "10")})

    def test_empty_mesh_is_flagged(self):
        with tempfile.TemporaryDirectory() as tmp:
            work = os.path.join(tmp, "work")
            here, readme = write_tables(
                tmp, "all step_rule adam\nall step_rule alternate x=1\n",
                "all ok quad\nall collapsed quad\n")
            write_run(work, "compare", "adam", "quad", [(0, 30), (5, 20)], True)
            write_run(work, "compare", "alternate", "quad", [(0, 30), (5, float("nan"))], True, 0)
            write_run(work, "stability", "ok", "quad", [(0, 30), (4, 25)], True)
            write_run(work, "stability", "collapsed", "quad", [(0, 30), (4, float("nan"))], True, 0)
            self.run_summarize("--mode", "full", "--work", work, "--here", here,
                               "--results", os.path.join(tmp, "res"), "--readme", readme,
                               "--run-seconds", "1", "--command", "test")
            with open(readme) as f:
                lines = f.read().splitlines()
            row = {l.split("|")[1].strip(): l for l in lines if l.startswith("| ")}
            self.assertIn("alternate (NO SURFACE)", row)
            self.assertIn("adam", row)
            self.assertEqual(row["ok"].split("|")[7].strip(), "yes")
            self.assertEqual(row["collapsed"].split("|")[7].strip(), "**none**")

    def test_step_rule_ratio(self):
        # Adam ends at F@2 85 % after 10 s. lm reaching it at 8 s gives 0.80;
        # lm ending below it after 12 s gives only the lower bound 12 / 10.
        for lm_points, expected in (([(0, 30), (8, 14)], "(lm) / Adam = 0.80**"),
                                    ([(0, 30), (12, 20)], "/ Adam > 1.20** (a lower bound")):
            with tempfile.TemporaryDirectory() as tmp:
                work = os.path.join(tmp, "work")
                here, readme = write_tables(
                    tmp, "all step_rule adam\nall step_rule lm stages[*].step_rule=lm\n", "")
                write_run(work, "compare", "adam", "quad", [(0, 30), (5, 20), (10, 15)], True)
                write_run(work, "compare", "lm", "quad", lm_points, True)
                self.run_summarize("--mode", "full", "--work", work, "--here", here,
                                   "--results", os.path.join(tmp, "res"), "--readme", readme,
                                   "--run-seconds", "1", "--command", "test")
                with open(readme) as f:
                    text = f.read()
                self.assertIn(expected, text)
                # Adam reaches its final F@2 only at its last point here.
                self.assertNotIn("Adam itself first reached", text)

    def test_step_rule_ratio_against_adams_first_time(self):
        # Adam passes its final F@2 (85 %) at 4 s, dips, and ends at 85 after
        # 10 s; lm reaches 85 at 8 s: 0.80 against the end, 2.00 against 4 s.
        with tempfile.TemporaryDirectory() as tmp:
            work = os.path.join(tmp, "work")
            here, readme = write_tables(
                tmp, "all step_rule adam\nall step_rule lm stages[*].step_rule=lm\n", "")
            write_run(work, "compare", "adam", "quad", [(0, 30), (4, 14), (7, 18), (10, 15)], True)
            write_run(work, "compare", "lm", "quad", [(0, 30), (8, 14)], True)
            self.run_summarize("--mode", "full", "--work", work, "--here", here,
                               "--results", os.path.join(tmp, "res"), "--readme", readme,
                               "--run-seconds", "1", "--command", "test")
            with open(readme) as f:
                text = f.read()
            self.assertIn("(lm) / Adam = 0.80**", text)
            self.assertIn("first reached the target after 4.0 s (10 batches): against that "
                          "time the ratio is 2.00.", text)

    def test_fox_runs_get_their_ratio_and_plot(self):
        with tempfile.TemporaryDirectory() as tmp:
            work = os.path.join(tmp, "work")
            here, readme = write_tables(tmp, "all step_rule adam\n", "")
            write_run(work, "compare", "adam", "quad", [(0, 30), (10, 15)], True)
            write_run(work, "fox", "fox_adam", "fox", [(0, 40), (30, 20)], True)
            write_run(work, "fox", "fox_lm", "fox", [(0, 40), (45, 19)], True)
            res = os.path.join(tmp, "res")
            self.run_summarize("--mode", "full", "--work", work, "--here", here,
                               "--results", res, "--readme", readme,
                               "--run-seconds", "1", "--command", "test")
            with open(readme) as f:
                text = f.read()
            self.assertIn("Fox, 30-minute budget: Adam's final F@2 = 80.0 % after 30.0 s", text)
            self.assertIn("**Ratio best Ceres rule (lm) / Adam = 1.50**", text)
            self.assertIn("- fox_step_rule: [", text)
            self.assertTrue(os.path.isfile(os.path.join(res, "plots", "full_fox_step_rule.png")))

    def test_quick_block_leaves_the_full_block_alone(self):
        with tempfile.TemporaryDirectory() as tmp:
            work = os.path.join(tmp, "work")
            here, readme = write_tables(tmp, "all step_rule adam\n", "")
            with open(readme, "w") as f:
                f.write("# x\n<!-- BEGIN solver-tables -->\nFULL RESULTS\n"
                        "<!-- END solver-tables -->\ntail\n")
            write_run(work, "compare", "adam", "quad", [(0, 30), (10, 15)], True)
            args = ["--mode", "quick", "--work", work, "--here", here, "--results",
                    os.path.join(tmp, "res"), "--readme", readme, "--run-seconds", "1"]
            for command in ("first", "second"):
                self.run_summarize(*args, "--command", command)
            with open(readme) as f:
                text = f.read()
            self.assertIn("<!-- BEGIN solver-tables -->\nFULL RESULTS\n"
                          "<!-- END solver-tables -->\ntail\n", text)
            # Appended once, then rewritten in place.
            self.assertEqual(text.count("<!-- BEGIN solver-tables-quick -->"), 1)
            self.assertEqual(text.count("<!-- END solver-tables-quick -->"), 1)
            self.assertIn("Command: `second`", text)
            self.assertNotIn("Command: `first`", text)
            self.assertIn("QUICK SMOKE RUN", text)

    def test_restore_without_results_is_a_no_op(self):
        with tempfile.TemporaryDirectory() as tmp:
            self.run_summarize("--restore", "--mode", "full", "--work",
                               os.path.join(tmp, "w"), "--results", os.path.join(tmp, "r"))
            self.assertFalse(os.path.exists(os.path.join(tmp, "w")))


if __name__ == "__main__":
    unittest.main()
