"""Tests of the blind-proof generator and scorer.

  python3 -m pytest scripts/blind_proof -q
  python3 scripts/blind_proof/test_blind.py
"""
from __future__ import annotations

import filecmp
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import generate as gen  # noqa: E402
import oracle  # noqa: E402
import score  # noqa: E402
import simulate as sim  # noqa: E402

PLAIN = {"de": 0.0103, "d0": 0.01, "alpha": 0.003, "beta": 0.03, "gamma": 0.015}


class TestOracle(unittest.TestCase):
    def test_classify(self):
        truth = ["creep", "delay"]
        free = {"bic": -1000.0, "validate_rmse": 1.0}
        at = lambda bic, v: {"bic": bic, "validate_rmse": v}  # noqa: E731
        self.assertEqual(oracle.classify(truth, ["creep"], at(-2000, 0.5), free), "not found alone")
        self.assertEqual(oracle.classify(truth, ["delay", "creep"], at(-1011, 0.99), free), "truth better supported")
        self.assertEqual(oracle.classify(truth, truth, at(-989, 1.01), free), "named set better supported")
        # Criteria that disagree, or a BIC difference inside the margin: a tie.
        self.assertEqual(oracle.classify(truth, truth, at(-1500, 1.2), free), "split")
        self.assertEqual(oracle.classify(truth, truth, at(-1005, 0.9), free), "split")


class TestWilson(unittest.TestCase):
    def test_known_values(self):
        # 0/n: upper = z^2 / (n + z^2) (hand-checked: 3.8415 / 23.8415 = 0.16112)
        lo, hi = score.wilson(0, 20)
        self.assertEqual(lo, 0.0)
        self.assertAlmostEqual(hi, 1.959963984540054 ** 2 / (20 + 1.959963984540054 ** 2), places=12)
        self.assertAlmostEqual(hi, 0.1611, places=4)
        lo, hi = score.wilson(19, 20)
        self.assertAlmostEqual(lo, 0.7639, places=4)
        self.assertAlmostEqual(hi, 0.9911, places=4)
        lo, hi = score.wilson(10, 20)  # symmetric about 1/2
        self.assertAlmostEqual(lo + hi, 1.0, places=12)
        self.assertAlmostEqual(lo, 0.2993, places=4)
        self.assertEqual(score.wilson(0, 0), (0.0, 1.0))
        lo, hi = score.wilson(20, 20)
        self.assertAlmostEqual(lo, 1 - 0.1611, places=4)
        self.assertEqual(hi, 1.0)

    def test_score_exact_match_and_dynamics_prefix(self):
        truth = lambda e: {"effects": e, "forms": {x: "f" for x in e}, "noise_sigma_mm": 1.0,  # noqa: E731
                            "target_ratio": 2.0, "achieved_ratio_linearised": 2.0}
        res = [
            {"id": "a", "truth": truth(["dynamics"]), "diagnosis": {"left_out": ["dynamics (two modes)"]}, "wall_s": 1},
            {"id": "b", "truth": truth(["creep"]), "diagnosis": {"left_out": ["creep", "delay"]}, "wall_s": 3},
            {"id": "c", "truth": truth([]), "diagnosis": {"left_out": []}, "wall_s": 2},
            {"id": "d", "truth": truth(["creep", "delay"]), "diagnosis": {"left_out": ["delay", "creep"]}, "wall_s": 2},
        ]
        s = score.score(res)
        self.assertEqual(s["per_effect"]["dynamics"]["k"], 1)
        self.assertEqual(s["per_effect"]["creep"]["k"], 0)
        self.assertEqual(s["singles"]["k"], 1)
        self.assertEqual(s["pairs"]["k"], 1)
        self.assertEqual(s["nulls_false_alarm"]["k"], 0)
        self.assertEqual(s["spurious"], {"delay": 1})
        self.assertEqual(s["wall_s"]["worst_case"], "b")
        self.assertEqual(s["wall_s"]["over_60s"], [])
        slow = [dict(r, wall_s=w) for r, w in zip(res, [61.0, 3, 75.5, 2])]
        self.assertEqual(score.score(slow)["wall_s"]["over_60s"], [("c", 75.5), ("a", 61.0)])
        self.assertIn("over 60 s: 2 (c 75.5 s, a 61.0 s)", score.markdown(score.score(slow)))
        self.assertIn("| creep |", score.markdown(s))
        t = truth(["dynamics"])
        t.update(target_reached=False, effect_settings={"dynamics": {"in_nominal_range": False, "at_bound": True}})
        self.assertEqual(len(score.generator_notes(t)), 3)
        self.assertEqual(score.generator_notes(truth([])), [])


class TestSimulator(unittest.TestCase):
    def test_bouc_wen_monotone_ramp_closed_form(self):
        v = np.linspace(0.0, 60.0, 3001)
        D = sim._bw_pass(v, PLAIN["de"], PLAIN["d0"], PLAIN["alpha"], PLAIN["beta"], PLAIN["gamma"],
                         0.0, np.zeros_like(v), 0.0, 0.0)
        h = PLAIN["de"] * v + PLAIN["d0"] - D
        k = PLAIN["beta"] + PLAIN["gamma"]
        np.testing.assert_allclose(h, PLAIN["alpha"] / k * (1 - np.exp(-k * v)), rtol=0, atol=1e-13)

    def test_bouc_wen_step_size_independent(self):
        # exact per step: a closed loop on a coarse and a fine grid ends in the same state
        t = np.linspace(0, 1, 201)
        coarse = 30 * np.sin(2 * np.pi * t) ** 2
        fine_t = np.linspace(0, 1, 2001)
        fine = 30 * np.sin(2 * np.pi * fine_t) ** 2
        args = (PLAIN["de"], PLAIN["d0"], PLAIN["alpha"], PLAIN["beta"], PLAIN["gamma"], 0.0)
        Dc = sim._bw_pass(coarse, *args, np.zeros_like(coarse), 0.0, 0.0)
        Df = sim._bw_pass(fine, *args, np.zeros_like(fine), 0.0, 0.0)
        # turning points at the same drive on both grids: same h
        self.assertAlmostEqual(Dc[-1], Df[-1], places=12)
        self.assertAlmostEqual(Dc[100], Df[1000], places=12)

    def test_first_order_lag_step_and_ramp(self):
        tau, h = 0.01, 1e-4
        n = 1001
        t = np.arange(n) * h
        step = np.ones(n)
        step[0] = 0.0
        y = sim.lti([[-1 / tau]], [1 / tau], [1.0], 0.0, step, h, zoh=False)
        # first-order hold: the step rises over the first interval; from then on exact
        y_zoh = sim.lti([[-1 / tau]], [1 / tau], [1.0], 0.0, np.r_[0.0, np.ones(n - 1)], h, zoh=True)
        # zoh: the held value over (t0, t1] is u[0] = 0, the step acts from t1
        np.testing.assert_allclose(y_zoh[1:], 1 - np.exp(-(t[1:] - h) / tau), atol=1e-12)
        ramp = t.copy()
        yr = sim.lti([[-1 / tau]], [1 / tau], [1.0], 0.0, ramp, h, zoh=False)
        np.testing.assert_allclose(yr, t - tau * (1 - np.exp(-t / tau)), atol=1e-12)
        self.assertTrue(np.all(np.diff(y) >= 0))

    def test_size_zero_is_plain(self):
        fs, M, N = 1000.0, 8, 2001
        rng = np.random.default_rng(3)
        st, fine, u = gen.signals.make_command(rng, "multisine", N, fs, M, "unipolar")
        consts = {"vref": sim.GAIN * 4.65, "rate_norm": 100.0}
        for hold in ["zoh", "linear", "bandlimited"]:
            cmd = sim.fine_command(u, M, hold, fine)
            plain = sim.simulate_record(cmd, 1 / fs, M, PLAIN, {}, consts, hold)
            for name in gen.EFFECTS:
                for form in gen.FORMS[name]:
                    e = gen.draw_effect(rng, name, fs)
                    while e["form"] != form:  # the form's own settings
                        e = gen.draw_effect(rng, name, fs)
                    e["size"] = 0.0
                    y = sim.simulate_record(cmd, 1 / fs, M, PLAIN, {name: e}, consts, hold)
                    self.assertTrue(np.array_equal(y, plain), f"{name}/{form}/{hold}")
                    e["size"] = e["bounds"][0] * 100
                    y2 = sim.simulate_record(cmd, 1 / fs, M, PLAIN, {name: e}, consts, hold)
                    if name != "offset-drift":  # the drift is the sensor's, added by generate.py
                        self.assertFalse(np.array_equal(y2, plain), f"{name}/{form}/{hold} size > 0")

    def test_hard_clip_and_delay(self):
        fs, M, N = 1000.0, 8, 501
        u = np.linspace(0.05, 4.65, N)
        cmd = sim.fine_command(u, M, "linear")
        consts = {"vref": sim.GAIN * 4.65, "rate_norm": 1.0}
        y0 = sim.simulate_record(cmd, 1 / fs, M, PLAIN, {}, consts, "linear")
        y1 = sim.simulate_record(cmd, 1 / fs, M, PLAIN, {"delay": {"form": "fractional", "size": 2.0}}, consts, "linear")
        np.testing.assert_allclose(y1[10:], y0[8:-2], atol=1e-12)  # a whole-sample delay shifts the output
        yc = sim.simulate_record(cmd, 1 / fs, M, PLAIN, {"saturation": {"form": "hard-clip", "size": 0.5}}, consts, "linear")
        self.assertAlmostEqual(np.ptp(yc[-100:]), 0.0, places=12)  # clipped: the output stops moving


class TestGenerator(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.built = {}
        for idx, eff in [(0, ["creep"]), (1, ["saturation"]), (2, ["dynamics", "offset-drift"]), (3, ["delay"])]:
            cls.built[idx] = gen.build_case(5, idx, eff, ci=True)

    def test_the_drive_between_samples_follows_the_hold(self):
        # The drawn hold shapes the drive the simulator sees: a staircase that jumps at
        # the samples, a straight line between them, or the continuous signal.
        seen = set()
        for idx in range(12):
            case = gen.draw_case(11, idx, ["creep"], ci=True)
            M = case["oversample"]
            for r in case["records"]:
                fine, u = r["fine"], r["u"]
                np.testing.assert_array_equal(fine[::M], u)
                mid = fine[M // 2::M][: u.shape[0] - 1]
                straight = u[:-1] + (M // 2) / M * np.diff(u)
                if case["hold"] == "zoh":
                    np.testing.assert_array_equal(mid, u[:-1])
                elif case["hold"] == "linear":
                    np.testing.assert_allclose(mid, straight, atol=1e-12)
                else:
                    # the continuous signal bends between samples
                    self.assertGreater(np.max(np.abs(mid - straight)), 1e-9)
            seen.add(case["hold"])
        self.assertEqual(seen, {"zoh", "linear", "bandlimited"})

    def test_calibration_hits_target(self):
        for idx, (truth, _) in self.built.items():
            if truth["target_reached"]:
                self.assertLess(abs(truth["achieved_ratio_linearised"] / truth["target_ratio"] - 1), 0.10, truth["effects"])
        self.assertGreaterEqual(sum(t["target_reached"] for t, _ in self.built.values()), 3)

    def test_calibration_independent_recheck(self):
        # recompute the linearised ratio from the written truth with a fresh case draw
        truth, _ = self.built[0]
        case = gen.draw_case(5, 0, ["creep"], ci=True, attempt=truth["attempts"] - 1)
        case["consts"] = truth["consts"]
        case["effects"]["creep"]["size"] = truth["sizes"]["creep"]
        lin = gen.Linearised(case)
        rem, _, rem_train = lin.remainder(*gen.sim_effects(case, case["effects"]))
        self.assertAlmostEqual(rem_train / truth["noise_sigma_mm"], truth["train_signature_sigma"], places=6)
        sig = truth["noise_sigma_mm"]
        self.assertAlmostEqual(math.sqrt(sig ** 2 + rem ** 2) / sig, truth["achieved_ratio_linearised"], places=6)

    def test_training_record_excites_the_effect(self):
        for truth, _ in self.built.values():
            if truth["effects"]:
                self.assertTrue(truth["train_signature_sigma"] >= gen.MIN_TRAIN_SIGNATURE
                                or truth["attempts"] == gen.MAX_ATTEMPTS, truth["effects"])
            else:
                self.assertEqual(truth["attempts"], 1)

    def test_each_effect_of_a_pair_excites_the_training_record(self):
        # Each effect alone, at its final size, recomputed from the written truth.
        truth, _ = self.built[2]
        case = gen.draw_case(5, 2, truth["effects"], ci=True, attempt=truth["attempts"] - 1)
        case["consts"] = truth["consts"]
        lin = gen.Linearised(case)
        for n in truth["effects"]:
            e = dict(case["effects"][n], size=truth["sizes"][n])
            rem_train = lin.remainder(*gen.sim_effects(case, {n: e}))[2]
            alone = truth["effect_settings"][n]["alone_train_signature_sigma"]
            self.assertAlmostEqual(rem_train / truth["noise_sigma_mm"], alone, places=6)
            self.assertTrue(alone >= gen.MIN_TRAIN_SIGNATURE or truth["attempts"] == gen.MAX_ATTEMPTS, n)

    def test_noise_and_quantisation(self):
        truth, recs = self.built[1]
        y = recs[0][1]
        q = truth["quant_step_mm"]
        self.assertTrue(np.allclose(y / q, np.round(y / q), atol=1e-6))
        self.assertTrue(0.001 <= truth["noise_fraction_of_stroke"] <= 0.005)
        self.assertTrue(0.05 <= truth["quant_fraction_of_sigma"] <= 0.3)

    def test_records_at_most_40000(self):
        for idx in range(40):
            case = gen.draw_case(11, idx, [], ci=False)
            for r in case["records"]:
                self.assertLessEqual(r["N"], gen.MAX_SAMPLES)
                self.assertEqual(r["u"].shape[0], r["N"])
            self.assertTrue(500 <= case["fs"] <= 5000)
            self.assertGreaterEqual(case["oversample"], 8)
            self.assertNotEqual(case["records"][0]["excitation"]["family"], case["records"][1]["excitation"]["family"])

    def test_pairs_compatible(self):
        self.assertNotIn(("delay", "input-lag"), gen.PAIRS)
        cl = gen.case_list(16, 30, 3, 9)
        self.assertEqual([c[1] for c in cl[:8]], [[e] for e in gen.EFFECTS])
        for _, e in cl[16:46]:
            self.assertEqual(len(e), 2)
            self.assertNotEqual(set(e), {"delay", "input-lag"})
        self.assertEqual([c[1] for c in cl[46:]], [[], [], []])


def _tree(root):
    out = {}
    for dp, _, fns in os.walk(root):
        for f in fns:
            p = os.path.join(dp, f)
            st = os.stat(p)
            out[os.path.relpath(p, root)] = (st.st_size, st.st_mtime_ns)
    return out


class TestGenerateCli(unittest.TestCase):
    def _run(self, out, cwd, tmp):
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", TMPDIR=tmp)
        subprocess.run([sys.executable, os.path.join(HERE, "generate.py"), "--out", out, "--master-seed", "4",
                        "--ci", "--only", "3,6,10"], check=True, cwd=cwd, env=env, capture_output=True)

    def test_deterministic_and_writes_only_out(self):
        with tempfile.TemporaryDirectory() as d:
            cwd, tmp = os.path.join(d, "cwd"), os.path.join(d, "tmp")
            os.makedirs(cwd)
            os.makedirs(tmp)
            before = _tree(HERE)
            self._run(os.path.join(d, "a"), cwd, tmp)
            self._run(os.path.join(d, "b"), cwd, tmp)
            self.assertEqual(_tree(HERE), before)
            self.assertEqual(os.listdir(cwd), [])
            self.assertEqual(os.listdir(tmp), [])
            self.assertEqual(sorted(os.listdir(d)), ["a", "b", "cwd", "tmp"])
            self.assertEqual(sorted(os.listdir(os.path.join(d, "a"))), ["case-0003", "case-0006", "case-0010"])
            for c in ["case-0003", "case-0006", "case-0010"]:
                for f in ["train.csv", "validate.csv"]:
                    self.assertTrue(filecmp.cmp(os.path.join(d, "a", c, f), os.path.join(d, "b", c, f), shallow=False))
                ta = json.load(open(os.path.join(d, "a", c, "truth.json")))
                tb = json.load(open(os.path.join(d, "b", c, "truth.json")))
                ta.pop("generate_s")
                tb.pop("generate_s")
                self.assertEqual(ta, tb)
                hdr = open(os.path.join(d, "a", c, "train.csv")).readline().strip()
                self.assertEqual(hdr, "t,u,y")
            self.assertEqual(json.load(open(os.path.join(d, "a", "case-0010", "truth.json")))["effects"], [])


if __name__ == "__main__":
    unittest.main()
