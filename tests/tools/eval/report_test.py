#!/usr/bin/env python3
"""tools/eval/report.py: the score-threshold table's reading of the daemon configuration and its
counts, on hand-made trials and configuration files (the bench's own data is far too slow to make
here). Usage: report_test.py REPO_ROOT"""
import importlib.util
import os
import sys
import tempfile
import unittest

ROOT = sys.argv.pop(1) if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..", "..")
spec = importlib.util.spec_from_file_location("report", os.path.join(ROOT, "tools", "eval", "report.py"))
report = importlib.util.module_from_spec(spec)
spec.loader.exec_module(report)


def write(text):
    f = tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False)
    f.write(text)
    f.close()
    return f.name


class MachineLine(unittest.TestCase):
    def test_cpu_and_yardstick_as_the_run_recorded_them(self):
        meta = {"cpu_model": "AMD EPYC", "cpu_mhz": "2245.78", "avx512": False, "yardstick_mhyp_s": 20.62}
        self.assertEqual(report.machine_cpu(meta), " (AMD EPYC at 2246 MHz, no AVX-512)")
        self.assertIn("at 20.6 M hypotheses/s", report.machine_yardstick(meta))

    def test_older_runs_without_them_say_nothing(self):
        # paper-run.json files written before the yardstick: the line reads as it did.
        self.assertEqual(report.machine_cpu({"cpus": 2}), "")
        self.assertEqual(report.machine_yardstick({"cpus": 2}), "")
        self.assertEqual(report.machine_cpu({"cpu_model": "X", "cpu_mhz": "", "avx512": True}), " (X, AVX-512)")


class ConfigMinScore(unittest.TestCase):
    def test_reads_the_pick_sections_key_only(self):
        # A min_score under another section, before and after, must not be taken for the pick one.
        path = write("vision:\n  min_score: 0.5\npick:\n  weight_score: 1.0\n  min_score: 0.07   # comment\n"
                     "other:\n  min_score: 0.9\n")
        self.assertAlmostEqual(report.config_min_score(path), 0.07)
        os.unlink(path)

    def test_missing_key_or_file_is_none(self):
        path = write("vision:\n  min_score: 0.5\npick:\n  weight_score: 1.0\n")
        self.assertIsNone(report.config_min_score(path))
        os.unlink(path)
        self.assertIsNone(report.config_min_score(path))

    def test_the_repositorys_configs_have_one(self):
        # The report labels its rows by these files: they must keep a pick.min_score.
        labels = [label for label, _ in report.cell_thresholds()]
        self.assertEqual(labels[0], "none")
        self.assertTrue(any("config/sim.yaml" in label for label in labels), labels)


class DeliveryCounts(unittest.TestCase):
    TRIALS = [
        {"correct": True, "found": True, "best_score": 0.30},
        {"correct": True, "found": True, "best_score": 0.05},
        {"correct": False, "found": True, "best_score": 0.20},
        {"correct": False, "found": True, "best_score": -0.10},
        {"correct": False, "found": False},
    ]

    def test_no_threshold_delivers_every_estimate(self):
        self.assertEqual(report.delivery_counts(self.TRIALS, None), (2, 2, 0, 1))

    def test_threshold_withholds_below_it(self):
        self.assertEqual(report.delivery_counts(self.TRIALS, 0.1), (1, 1, 1, 2))
        self.assertEqual(report.delivery_counts(self.TRIALS, 0.05), (2, 1, 0, 2))  # at the threshold: delivered

    def test_table_rows_match_the_counts(self):
        lines = []
        report.picks_at_threshold(lines.append, [("bins", self.TRIALS), ("empty", [])], [("none", None), ("0.1", 0.1)])
        rows = [line for line in lines if line.startswith("| bins")]
        self.assertEqual(rows, ["| bins | none | 2 | 2 | 0 | 1 | 0.50 |", "| bins | 0.1 | 1 | 1 | 1 | 2 | 0.50 |"])
        self.assertFalse(any(line.startswith("| empty") for line in lines))


class EscalationNote(unittest.TestCase):
    def test_counts_and_times_of_the_escalated_detections(self):
        lines = []
        trials = [{"escalated": True, "times": {"total": 200.0}}, {"escalated": False, "times": {"total": 50.0}},
                  {"escalated": True, "times": {"total": 300.0}}]
        report.escalation_note(lines.append, [("one part type", trials), ("all six", [])])
        self.assertEqual(len(lines), 1)
        self.assertIn("one part type: 2 of 3, median 250 ms, at most 300 ms", lines[0])
        self.assertNotIn("all six", lines[0])

    def test_runs_without_the_field_say_nothing(self):
        lines = []
        report.escalation_note(lines.append, [("one part type", [{"times": {"total": 50.0}}])])
        self.assertEqual(lines, [])


class GraspFeatures(unittest.TestCase):
    TRIALS = [
        {"truth_scores": [
            {"grasp": {"true": 0.0, "estimated": 0.1, "faces_camera": True}},
            {"grasp": {"true": 0.0, "estimated": 0.0, "faces_camera": False}},  # turned away: not counted
            {"grasp": {"true": 0.3, "estimated": 0.5, "faces_camera": True}}]},
        {"truth_scores": [
            {"grasp": {"true": 0.95, "estimated": 0.9, "faces_camera": True}},
            {"grasp": {"true": 1.0, "estimated": 0.2, "faces_camera": True}},
            {"visib_fract": 0.5}]},  # a run without grasp features
    ]

    def test_estimate_rows_bin_by_the_truth(self):
        rows = report.grasp_estimate_rows(self.TRIALS, 0.3)
        self.assertEqual([r[0] for r in rows][0], "covered (0)")
        self.assertEqual([(n, taken) for _, n, _, taken in rows], [(1, 0), (1, 1), (0, 0), (2, 1)])
        self.assertIsNone(rows[2][2])
        self.assertAlmostEqual(rows[3][2], 0.55)

    def test_cell_pick_counts_per_setting(self):
        def cell(picked, correct=True, free=1.0):
            c = {"grasp_weight": 0.5, "min_grasp_visibility": 0.3, "picked": picked}
            if picked:
                c.update({"correct": correct, "grasp_true": free})
            return c
        picks = [{"cell": [dict(cell(True), grasp_weight=0, min_grasp_visibility=0), cell(True)]},
                 {"cell": [dict(cell(True, free=0.2), grasp_weight=0, min_grasp_visibility=0), cell(False)]},
                 {"cell": [dict(cell(True, correct=False), grasp_weight=0, min_grasp_visibility=0),
                           cell(True, free=0.5)]}]
        self.assertEqual(report.cell_pick_counts(picks), [(0, 0, 3, 1, 1, 1, 0), (0.5, 0.3, 3, 2, 0, 0, 1)])
        self.assertEqual(report.cell_pick_counts([{"correct": True}]), [])
        self.assertEqual(report.cell_pick_counts([]), [])

    def test_no_pick_breakdown_counts_the_candidates_of_images_without_a_pick(self):
        setting = {"grasp_weight": 0.5, "min_grasp_visibility": 0.3}
        picks = [
            {"cell": [dict(setting, picked=True), dict(setting, picked=False)],
             "candidates": [{"score": 0.4, "grasp_estimated": 0.0, "correct": True, "grasp_true": 0.0},
                            {"score": 0.2, "grasp_estimated": 0.1, "correct": False, "grasp_true": 0.0},
                            {"score": 0.05, "grasp_estimated": 0.9, "correct": True, "grasp_true": 1.0}]},
            {"cell": [dict(setting, picked=True), dict(setting, picked=True)],
             "candidates": [{"score": 0.4, "grasp_estimated": 0.9, "correct": True, "grasp_true": 1.0}]},
        ]
        self.assertEqual(report.no_pick_breakdown(picks), (1, 2, 2, 1, 1))


if __name__ == "__main__":
    unittest.main()
