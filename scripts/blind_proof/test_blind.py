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
        # A miss the tool declared a tie with the truth is reported as such, still a miss.
        tied = {"left_out": ["delay"], "candidates": [
            {"name": "delay", "accepted": True, "ties": [{"name": "input-lag", "form": "first-order"}]}]}
        untied = {"left_out": ["delay"], "candidates": [{"name": "delay", "accepted": True, "ties": []}]}
        st = score.score([{"id": "e", "truth": truth(["input-lag"]), "diagnosis": tied, "wall_s": 1},
                          {"id": "f", "truth": truth(["input-lag"]), "diagnosis": untied, "wall_s": 1}])
        self.assertEqual(st["singles"]["k"], 0)
        self.assertEqual(st["declared_ties"], {"singles": 1, "pairs": 0})
        self.assertEqual([f["declared_tie"] for f in st["failed"]], [True, False])
        self.assertIn("(declared tie)", score.markdown(st))
        self.assertFalse(score.declared_tie(["creep", "delay"], ["delay"], tied))
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


# ---------------------------------------------------------------- out of vocabulary
OOV_CONSTS = {"vref": sim.GAIN * 4.65, "rate_norm": 1.0, "stroke": 0.5, "y_mid": 0.25,
              "v_mid": sim.GAIN * 2.35, "v_half": sim.GAIN * 2.3, "p_ref": 1000.0, "hp_ref": 0.01}


def _oov_effect(name, form, size, **kw):
    e = gen.draw_oov(np.random.default_rng(0), name, 1000.0)
    e.update(form=form, size=size, **kw)
    return e


class TestOovSimulator(unittest.TestCase):
    fs, M = 1000.0, 8

    def _sim(self, u, effects, hold="linear"):
        cmd = sim.fine_command(np.asarray(u, float), self.M, hold)
        return sim.simulate_record(cmd, 1 / self.fs, self.M, PLAIN, effects, OOV_CONSTS, hold)

    def test_size_zero_is_plain_and_positive_size_is_not(self):
        rng = np.random.default_rng(4)
        st, fine, u = gen.signals.make_command(rng, "multisine", 2001, self.fs, self.M, "unipolar")
        for hold in ["zoh", "linear", "bandlimited"]:
            cmd = sim.fine_command(u, self.M, hold, fine)
            plain = sim.simulate_record(cmd, 1 / self.fs, self.M, PLAIN, {}, OOV_CONSTS, hold)
            for name in gen.OOV_KINDS:
                if name == "mains":  # the sensor's, added by generate.py (TestOovGenerator)
                    continue
                for form in gen.OOV_FORMS[name]:
                    e = _oov_effect(name, form, 0.0)
                    y = sim.simulate_record(cmd, 1 / self.fs, self.M, PLAIN, {name: e}, OOV_CONSTS, hold)
                    self.assertTrue(np.array_equal(y, plain), f"{name}/{form}/{hold}")
                    e["size"] = e["bounds"][0] * 100
                    y2 = sim.simulate_record(cmd, 1 / self.fs, self.M, PLAIN, {name: e}, OOV_CONSTS, hold)
                    self.assertFalse(np.array_equal(y2, plain), f"{name}/{form}/{hold} size > 0")

    def test_play_holds_inside_the_gap(self):
        r = 0.1
        x = np.r_[np.linspace(0.0, 1.0, 101), np.linspace(1.0, 0.85, 16), np.linspace(0.85, 1.2, 36)]
        y = sim.play(x, r)
        np.testing.assert_allclose(y[:101], np.maximum(x[:101] - r, 0.0), atol=1e-15)  # dragged at the back edge
        self.assertTrue(np.all(y[100:133] == y[100]))  # down 0.15 < 2r, back up to 1.0 (x[132]): no motion
        np.testing.assert_allclose(y[-1], 1.2 - r, atol=1e-15)  # pushed again once past the old edge

    def test_backlash_output_constant_while_the_drive_reverses_inside_the_gap(self):
        u = np.r_[np.linspace(0.5, 4.0, 400), np.linspace(4.0, 3.9, 50)[1:], np.linspace(3.9, 4.0, 50)[1:]]
        plain = self._sim(u, {})
        rev = plain[399:]
        swing = np.ptp(rev)  # the actuator's motion during the reversal
        gap = 1.5 * swing
        y = self._sim(u, {"backlash": _oov_effect("backlash", "play", gap / OOV_CONSTS["stroke"])})
        self.assertGreater(swing, 1e-3)
        # down by less than the gap and back: the target stays until the actuator passes its turning point
        inside = rev <= rev[0]
        self.assertGreater(inside.sum(), 60)
        self.assertAlmostEqual(np.ptp(y[399:][inside]), 0.0, places=14)
        # before and after: dragged behind the actuator by half the gap
        np.testing.assert_allclose(y[100:399], plain[100:399] - gap / 2, atol=1e-12)
        np.testing.assert_allclose(y[399:][~inside], rev[~inside] - gap / 2, atol=1e-12)

    def test_dead_zone_no_response_inside_and_shifted_drive_outside(self):
        mid = 2.35
        e = _oov_effect("dead-zone", "crossover", 0.1)  # half-width 0.23 command volts
        hw = 0.1 * 2.3
        u_in = mid + 0.9 * hw * np.sin(np.linspace(0, 6 * np.pi, 600))
        y_in = self._sim(u_in, {"dead-zone": e})
        self.assertAlmostEqual(np.ptp(y_in), 0.0, places=14)  # zero response below the dead band
        self.assertFalse(np.ptp(self._sim(u_in, {})) < 1e-6)
        u_out = np.linspace(mid + 1.5 * hw, 4.5, 500)
        np.testing.assert_allclose(self._sim(u_out, {"dead-zone": e}), self._sim(u_out - hw, {}), atol=1e-12)

    def test_thermal_grows_with_power_independent_of_sign(self):
        dtf = 1e-3
        v = 30.0 * np.sin(np.linspace(0, 40 * np.pi, 20001))
        for form in ["joule", "dielectric"]:
            e = _oov_effect("thermal", form, 1.0, tau_s=3.0, start=0.0)
            a = sim.thermal_term(v, dtf, e, 100.0)
            np.testing.assert_array_equal(a, sim.thermal_term(-v, dtf, e, 100.0))  # even in the drive
            b = sim.thermal_term(2 * v, dtf, e, 100.0)  # twice the drive: 4x the power, 4x the term
            np.testing.assert_allclose(b, 4 * a, rtol=1e-12, atol=1e-12)
            self.assertTrue(np.all(np.diff(a[::500]) > 0))  # heating from cold under a steady drive
        # constant power: the first-order step response exactly
        e = _oov_effect("thermal", "joule", 1.0, tau_s=2.0, start=0.0)
        t = np.arange(5001) * dtf
        np.testing.assert_allclose(sim.thermal_term(np.full(5001, 10.0), dtf, e, 50.0),
                                   2.0 * (1 - np.exp(-t / 2.0)), atol=1e-12)
        e["start"] = 1.0  # warm start: already at the record's mean power
        np.testing.assert_allclose(sim.thermal_term(np.full(5001, 10.0), dtf, e, 50.0), 2.0, atol=1e-12)
        # in the simulator: a bipolar drive and its mirror leave the same thermal term
        u = 2.0 * np.sin(np.linspace(0, 8 * np.pi, 3001))
        e = _oov_effect("thermal", "dielectric", 0.05, tau_s=2.0, start=0.0, sign=1.0)
        c = dict(OOV_CONSTS, v_mid=0.0)
        cmd = sim.fine_command(u, self.M, "linear")
        cmd_m = sim.fine_command(-u, self.M, "linear")
        run = lambda cm, ef: sim.simulate_record(cm, 1 / self.fs, self.M, PLAIN, ef, c, "linear")  # noqa: E731
        np.testing.assert_allclose(run(cmd, {"thermal": e}) - run(cmd, {}), run(cmd_m, {"thermal": e}) - run(cmd_m, {}),
                                   atol=1e-13)

    def test_sensor_nonlinearity_exact_formula(self):
        u = np.linspace(0.2, 4.5, 800)
        plain = self._sim(u, {})
        S, ym = OOV_CONSTS["stroke"], OOV_CONSTS["y_mid"]
        e = _oov_effect("sensor-nonlinearity", "quadratic", 0.07, sign=-1.0)
        np.testing.assert_allclose(self._sim(u, {"sensor-nonlinearity": e}), plain - 0.07 * (plain - ym) ** 2 / S,
                                   rtol=0, atol=1e-14)
        e = _oov_effect("sensor-nonlinearity", "periodic", 0.002, sign=1.0, periods_per_stroke=7.0, phase=0.3)
        np.testing.assert_allclose(self._sim(u, {"sensor-nonlinearity": e}),
                                   plain + 0.002 * S * np.sin(2 * np.pi * (plain - ym) * 7.0 / S + 0.3), rtol=0, atol=1e-14)

    def test_feed_through_follows_the_drive_rate(self):
        tau = 2e-4
        e = _oov_effect("feed-through", "capacitive", 0.01, tau_s=tau, sign=1.0)
        k = 0.01 * OOV_CONSTS["stroke"] / OOV_CONSTS["hp_ref"]
        u = np.r_[np.full(200, 1.0), np.linspace(1.0, 3.0, 801)[1:], np.full(300, 3.0)]
        d = self._sim(u, {"feed-through": e}) - self._sim(u, {})
        np.testing.assert_allclose(d[:200], 0.0, atol=1e-15)  # a constant drive couples nothing
        rate = sim.GAIN * 2.0 / (800 / self.fs)  # drive V/s on the ramp
        np.testing.assert_allclose(d[300:999], k * tau * rate, rtol=1e-9)  # settled: k tau dv/dt
        self.assertLess(abs(d[-1]), 1e-12 * k)  # decays after the ramp


class TestOovGenerator(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.built = {k: gen.build_case(5, 100 + i, [k], ci=True) for i, k in enumerate(gen.OOV_KINDS)}

    def test_truth_marks_oov(self):
        for k, (truth, _) in self.built.items():
            self.assertEqual(truth["oov"], k)
            self.assertEqual(truth["kind"], "oov")
            self.assertEqual(truth["effects"], [])
            self.assertIn(truth["oov_form"], gen.OOV_FORMS[k])
            self.assertEqual(truth["forms"], {k: truth["oov_form"]})
            self.assertIn("size", truth["effect_settings"][k])

    def test_calibration_hits_target(self):
        for k, (truth, _) in self.built.items():
            self.assertTrue(1.5 <= truth["target_ratio"] <= 4.0)
            self.assertTrue(truth["target_reached"], k)
            self.assertLess(abs(truth["achieved_ratio_linearised"] / truth["target_ratio"] - 1), 0.05, k)
            self.assertTrue(truth["train_signature_sigma"] >= gen.MIN_TRAIN_SIGNATURE
                            or truth["attempts"] == gen.MAX_ATTEMPTS, k)

    def test_calibration_independent_recheck(self):
        # The linearised ratio recomputed from the written truth with a fresh draw (mains: the sensor's term).
        for k in ["mains", "thermal"]:
            truth, _ = self.built[k]
            idx = 100 + gen.OOV_KINDS.index(k)
            case = gen.draw_case(5, idx, [k], ci=True, attempt=truth["attempts"] - 1)
            case["consts"] = truth["consts"]
            case["effects"][k]["size"] = truth["sizes"][k]
            lin = gen.Linearised(case)
            rem, _, _ = lin.remainder(*gen.sim_effects(case, case["effects"]))
            sig = truth["noise_sigma_mm"]
            self.assertAlmostEqual(math.sqrt(sig ** 2 + rem ** 2) / sig, truth["achieved_ratio_linearised"], places=6)

    def test_mains_independent_of_the_input(self):
        truth, _ = self.built["mains"]
        idx = 100 + gen.OOV_KINDS.index("mains")
        case = gen.draw_case(5, idx, ["mains"], ci=True, attempt=truth["attempts"] - 1)
        case["consts"] = truth["consts"]
        e = dict(case["effects"]["mains"], size=truth["sizes"]["mains"])
        d = [a - b for a, b in zip(gen.sim_effects(case, {"mains": e}), gen.sim_effects(case, {}))]
        for r, di, ph in zip(case["records"], d, truth["effect_settings"]["mains"]["phases_rad"]):
            t = np.arange(r["N"]) / case["fs"]
            w = 2 * np.pi * e["freq_hz"]
            want = e["size"] * truth["stroke_mm"] * (np.sin(w * t + ph[0]) + e["third_harmonic"] * np.sin(3 * w * t + ph[1]))
            np.testing.assert_allclose(di, want, rtol=1e-9, atol=1e-12)
        self.assertTrue(49.8 <= e["freq_hz"] <= 60.2)

    def test_case_list_appends_oov_after_the_rest(self):
        base = gen.case_list(16, 5, 3, 9)
        more = gen.case_list(16, 5, 3, 9, oov=8)
        self.assertEqual(more[:len(base)], base)
        self.assertEqual([c[1] for c in more[len(base):]], [[k] for k in gen.OOV_KINDS] + [gen.OOV_KINDS[:1], gen.OOV_KINDS[1:2]])
        self.assertEqual([c[0] for c in more], list(range(len(more))))


# Files of cases generated before the out-of-vocabulary part existed (commit 6da7d63, master
# seed 4, --ci): sha256 (first 16 hex digits) of train.csv, validate.csv and truth.json less
# its timing (json.dumps, sort_keys). The eight effects' simulations and draws are unchanged.
PINNED = {
    2: ("saturation", "9aace5a1ef860015", "e5406eaa23c3ae91", "380d55cbe773cf8d"),
    4: ("rate-dependence", "b3e2c11fc98326ce", "ef720e83086942a2", "9f95b460aff18f16"),
    6: ("dynamics", "5345af002d71153b", "9784cdb86b3ff58c", "87a182af42c4a773"),
    8: ("delay+rate-dependence", "504b333c82404352", "c2470325e8f59055", "b7f2b3b4047f78cb"),
    11: ("none", "1d621623f8cd35ea", "90b34d8335448da5", "2f4a284b0eebef08"),
}


class TestExistingCasesUnchanged(unittest.TestCase):
    def test_pinned_hashes(self):
        import hashlib
        h = lambda b: hashlib.sha256(b).hexdigest()[:16]  # noqa: E731
        with tempfile.TemporaryDirectory() as d:
            for idx, (label, *want) in PINNED.items():
                effects = [] if label == "none" else label.split("+")
                # the --ci list, and the same list with OOV cases appended, give this case these effects
                self.assertEqual(dict(gen.case_list(8, 2, 2, 4))[idx], effects)
                self.assertEqual(dict(gen.case_list(8, 2, 2, 4, oov=5))[idx], effects)
                truth = gen.write_case(d, 4, idx, effects, True)
                c = os.path.join(d, f"case-{idx:04d}")
                got = [h(open(os.path.join(c, f), "rb").read()) for f in ["train.csv", "validate.csv"]]
                truth.pop("generate_s")
                got.append(h(json.dumps(truth, sort_keys=True).encode()))
                self.assertEqual(got, want, f"case {idx} ({label})")


def _diag(named, unexplained, final, floor=1.0, **kw):
    return {"left_out": named, "unexplained": unexplained, "final": {"validate_rmse": final},
            "baseline": {"validate_rmse": 3.0}, "noise_floor": floor, **kw}


class TestOovScore(unittest.TestCase):
    def test_verdicts(self):
        v = score.oov_verdict
        # (a) the tool says structure is left and what it depends on: pass, whatever it named
        ov = {"outside_vocabulary": {"depends_on": [{"feature": "direction", "gain": 0.4}]}}
        self.assertEqual(v(_diag([], True, 2.5, **ov))["outcome"], "unexplained")
        self.assertTrue(v(_diag([], True, 2.5, **ov))["pass"])
        self.assertTrue(v(_diag(["creep"], True, 2.5, **ov))["pass"])
        self.assertTrue(v(_diag([], True, 2.5, **ov))["strict"])
        self.assertFalse(v(_diag(["creep"], True, 2.5, **ov))["strict"])  # a name beside the flag: not strict
        self.assertTrue(v(_diag(["creep"], True, 1.1))["strict"])
        self.assertEqual(v(_diag([], True, 2.5, **ov))["outside_vocabulary"], ["direction"])
        # flagged but not characterised: fail
        self.assertFalse(v(_diag(["creep"], True, 2.5))["pass"])
        self.assertEqual(v(_diag([], True, 2.5))["outcome"], "not characterised")
        # (b) the names (or the plain model) fit to the noise: pass
        self.assertTrue(v(_diag(["saturation"], False, 1.15))["pass"])
        self.assertEqual(v(_diag(["saturation"], False, 1.1))["outcome"], "approximated by the names")
        self.assertTrue(v(_diag([], False, 1.05))["pass"])
        self.assertAlmostEqual(v(_diag([], False, 2.2, floor=2.0))["final_over_floor"], 1.1)
        # a name claimed with confidence above 1.15x the floor, or nothing named and nothing flagged: fail
        self.assertFalse(v(_diag(["creep"], False, 1.2))["pass"])
        self.assertEqual(v(_diag(["creep"], False, 1.2))["outcome"], "confident wrong name")
        self.assertFalse(v(_diag([], False, 1.5))["pass"])
        self.assertEqual(v(_diag([], False, 1.5))["outcome"], "silent")
        # the characterisation is reported
        self.assertIsNone(v(_diag([], True, 2.0))["outside_vocabulary"])
        d = _diag([], True, 2.0, outside_vocabulary={"depends_on": ["drive power", "time"]})
        self.assertEqual(v(d)["outside_vocabulary"], ["drive power", "time"])

    def test_score_keeps_oov_apart(self):
        tr = lambda e, oov=None: {"effects": e, "forms": {}, "noise_sigma_mm": 0.5, "target_ratio": 2.0,  # noqa: E731
                                  "achieved_ratio_linearised": 2.0, **({"oov": oov, "oov_form": "f"} if oov else {})}
        res = [
            {"id": "n", "truth": tr([]), "diagnosis": _diag([], False, 1.0), "wall_s": 1},
            {"id": "o1", "truth": tr([], "backlash"), "diagnosis": _diag(["asymmetry"], False, 2.0), "wall_s": 9},
            {"id": "o2", "truth": tr([], "backlash"),
             "diagnosis": _diag([], True, 2.0, outside_vocabulary={"depends_on": []}), "wall_s": 1},
            {"id": "o3", "truth": tr([], "mains"), "diagnosis": _diag(["dynamics (one mode)"], False, 1.1), "wall_s": 1},
        ]
        s = score.score(res)
        self.assertEqual(s["nulls_false_alarm"]["n"], 1)  # OOV cases are not nulls
        self.assertEqual(s["overall"]["n"], 1)
        self.assertEqual([f["id"] for f in s["failed"]], [])
        self.assertEqual(s["wall_s"]["worst_case"], "o1")
        o = s["oov"]
        self.assertEqual((o["overall"]["k"], o["overall"]["n"]), (2, 3))
        self.assertEqual((o["per_kind"]["backlash"]["k"], o["per_kind"]["backlash"]["n"]), (1, 2))
        self.assertEqual(o["per_kind"]["mains"]["named"], {"dynamics": 1})
        self.assertEqual(o["outcomes"], {"confident wrong name": 1, "unexplained": 1, "approximated by the names": 1})
        self.assertEqual(o["strict"]["k"], 2)
        md = score.markdown(s)
        self.assertIn("## Out of vocabulary", md)
        self.assertIn("| o1 | backlash (f) | asymmetry | no | 2.00 | 4.00 |", md)
        self.assertIn("FAIL: confident wrong name", md)
        self.assertNotIn("## Out of vocabulary", score.markdown(score.score(res[:1])))

    def test_run_min_oov(self):
        with tempfile.TemporaryDirectory() as d:
            for i, (named, unexpl, fin) in enumerate([(["creep"], False, 2.0), ([], True, 2.0)]):
                c = os.path.join(d, f"case-{i:04d}")
                os.makedirs(os.path.join(c, "diagnosis"))
                json.dump({"effects": [], "forms": {"thermal": "joule"}, "oov": "thermal", "oov_form": "joule",
                           "noise_sigma_mm": 1.0, "target_ratio": 2.0, "achieved_ratio_linearised": 2.0},
                          open(os.path.join(c, "truth.json"), "w"))
                ov = {"outside_vocabulary": {"depends_on": []}} if unexpl else {}
                json.dump(_diag(named, unexpl, fin, **ov), open(os.path.join(c, "diagnosis", "diagnosis.json"), "w"))
            run = lambda *x: subprocess.run([sys.executable, os.path.join(HERE, "run.py"), "--cases", d,  # noqa: E731
                                             "--score-only", "--json", os.path.join(d, "r.json"), *x],
                                            capture_output=True, text=True)
            p = run("--min-oov", "0.5")
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertEqual(json.load(open(os.path.join(d, "r.json")))["oov"]["overall"]["k"], 1)
            p = run("--min-oov", "0.75")
            self.assertNotEqual(p.returncode, 0)
            self.assertIn("out-of-vocabulary passes 1/2 below 75%", p.stderr)


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

    def test_oov_presets_number_after_the_rest(self):
        with tempfile.TemporaryDirectory() as d:
            env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
            for args, idx in [(["--ci", "--ci-oov", "--only", "12"], 12), (["--ci-oov", "--only", "0"], 0),
                              (["--singles", "0", "--oov", "3", "--seconds", "5", "6", "--only", "1"], 1)]:
                out = os.path.join(d, str(idx))
                p = subprocess.run([sys.executable, os.path.join(HERE, "generate.py"), "--out", out, "--master-seed", "2",
                                    *args], check=True, env=env, capture_output=True, text=True)
                self.assertIn(f"case-{idx:04d} oov:", p.stdout)
                t = json.load(open(os.path.join(out, f"case-{idx:04d}", "truth.json")))
                self.assertEqual(t["oov"], gen.OOV_KINDS[1 if idx == 1 else 0])
                if idx == 1:
                    self.assertTrue(all(5.0 <= r["seconds"] <= 6.0 for r in t["records"]))
                else:
                    self.assertLessEqual(t["fs_hz"], 2000.0)  # the --ci record settings


if __name__ == "__main__":
    unittest.main()
