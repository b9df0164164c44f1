"""render_bin.py --second-view-deg: the second camera's pose (benchgen_common.second_view_pose) and
check_scene.py's views rule (check_views) on scene files made in code."""

import contextlib
import copy
import io
import math
import os
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', '..', '..', 'tools', 'benchgen'))
import check_scene  # noqa: E402
from benchgen_common import second_view_pose  # noqa: E402


class SecondViewPose(unittest.TestCase):
    def test_turns_about_the_pivot_towards_the_top_of_image_0(self):
        floor = 305.0
        for deg in (-40.0, 12.5, 25.0, 60.0):
            R, t = second_view_pose(deg, floor)
            self.assertLess(np.abs(R @ R.T - np.eye(3)).max(), 1e-12)
            self.assertAlmostEqual(np.linalg.det(R), 1.0, places=12)
            c = np.array([0.0, 0.0, floor])
            np.testing.assert_allclose(R @ c + t, c, atol=1e-9)  # the pivot stays on the axis, as far
            a = math.radians(deg)
            centre = -R.T @ t  # camera 1's centre in camera 0's frame
            np.testing.assert_allclose(centre, [0.0, -floor * math.sin(a), floor * (1 - math.cos(a))], atol=1e-9)
            np.testing.assert_allclose(R[2], [0.0, math.sin(a), math.cos(a)], atol=1e-12)  # its optical axis
            np.testing.assert_allclose(R @ [1.0, 0.0, 0.0], [1.0, 0.0, 0.0])  # turned about x
            self.assertEqual(np.sign(centre[1]), -np.sign(deg))  # deg > 0: above image 0's top edge

    def test_zero_is_camera_0(self):
        R, t = second_view_pose(0.0, 300.0)
        np.testing.assert_array_equal(R, np.eye(3))
        np.testing.assert_array_equal(t, np.zeros(3))


def rotation(rng):
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def two_view_scene(deg=25.0, floor=300.0, n=4, seed=1):
    """scene_camera and scene_gt dicts of a scene seen by camera 0 and its second view."""
    rng = np.random.default_rng(seed)
    R, t = second_view_pose(deg, floor)
    cams = {'0': {'cam_R_w2c': np.eye(3).ravel().tolist(), 'cam_t_w2c': [0.0, 0.0, 0.0]},
            '1': {'cam_R_w2c': R.ravel().tolist(), 'cam_t_w2c': t.tolist()}}
    gts = {'0': [], '1': []}
    for g in range(n):
        Rm, tm = rotation(rng), np.array([rng.uniform(-80, 80), rng.uniform(-60, 60), floor - rng.uniform(5, 40)])
        oid = int(rng.integers(1, 4))
        gts['0'].append({'obj_id': oid, 'cam_R_m2c': Rm.ravel().tolist(), 'cam_t_m2c': tm.tolist()})
        gts['1'].append({'obj_id': oid, 'cam_R_m2c': (R @ Rm).ravel().tolist(), 'cam_t_m2c': (R @ tm + t).tolist()})
    return cams, gts


class ViewsRule(unittest.TestCase):
    def failures(self, cams, gts):
        chk = check_scene.Checker()
        with contextlib.redirect_stdout(io.StringIO()):  # its FAIL lines: the tests read chk.failures
            out = check_scene.check_views(chk, cams, gts)
        return chk.failures, out

    def test_consistent_scene_passes(self):
        fails, (dr, dt) = self.failures(*two_view_scene())
        self.assertEqual(fails, [])
        self.assertLess(dr, 1e-12)
        self.assertLess(dt, 1e-9)

    def test_image_0_need_not_be_the_world(self):
        cams, gts = two_view_scene()
        Rw, tw = rotation(np.random.default_rng(7)), np.array([10.0, -20.0, 5.0])  # another world frame
        for k in cams:
            R, t = np.array(cams[k]['cam_R_w2c']).reshape(3, 3), np.array(cams[k]['cam_t_w2c'])
            cams[k] = {'cam_R_w2c': (R @ Rw).ravel().tolist(), 'cam_t_w2c': (R @ tw + t).tolist()}
        self.assertEqual(self.failures(cams, gts)[0], [])

    def test_one_image_without_camera_pose_is_not_judged(self):
        cams, gts = two_view_scene()
        fails, out = self.failures({'0': {}}, {'0': gts['0']})
        self.assertEqual((fails, out), ([], None))

    def test_wrong_second_pose_fails(self):
        cams, gts = two_view_scene()
        for key, delta in (('cam_t_m2c', 2e-3), ('cam_R_m2c', 1e-5)):
            bad = copy.deepcopy(gts)
            bad['1'][2][key][1] += delta
            fails, _ = self.failures(cams, bad)
            self.assertEqual(len(fails), 1, fails)
            self.assertIn('instance 2', fails[0])
        bad = copy.deepcopy(gts)  # image 0's pose instead: the camera's motion forgotten
        bad['1'] = copy.deepcopy(gts['0'])
        self.assertEqual(len(self.failures(cams, bad)[0]), len(gts['0']))

    def test_sign_of_the_turn_matters(self):
        cams, gts = two_view_scene(deg=25.0)
        R, t = second_view_pose(-25.0, 300.0)
        cams['1'] = {'cam_R_w2c': R.ravel().tolist(), 'cam_t_w2c': t.tolist()}
        self.assertEqual(len(self.failures(cams, gts)[0]), len(gts['0']))

    def test_malformed_cameras_fail(self):
        cams, gts = two_view_scene()
        no_pose = copy.deepcopy(cams)
        del no_pose['1']['cam_R_w2c'], no_pose['1']['cam_t_w2c']
        self.assertEqual(len(self.failures(no_pose, gts)[0]), 1)
        none = {'0': {}, '1': {}}
        self.assertEqual(len(self.failures(none, gts)[0]), 1)
        scaled = copy.deepcopy(cams)
        scaled['1']['cam_R_w2c'] = (1.001 * np.array(cams['1']['cam_R_w2c'])).tolist()
        fails, _ = self.failures(scaled, gts)
        self.assertTrue(any('not a rotation' in f for f in fails), fails)
        short = copy.deepcopy(cams)
        short['1']['cam_t_w2c'] = [0.0, 1.0]
        self.assertTrue(any('3' in f for f in self.failures(short, gts)[0]))

    def test_other_instances_fail(self):
        cams, gts = two_view_scene()
        bad = copy.deepcopy(gts)
        bad['1'] = bad['1'][:-1]
        self.assertEqual(len(self.failures(cams, bad)[0]), 1)

    def test_overlay_names(self):
        self.assertEqual(check_scene.overlay_path('/x/overlay.png', 0, 0), '/x/overlay.png')
        self.assertEqual(check_scene.overlay_path('/x/overlay.png', 1, 0), '/x/overlay-000001.png')
        self.assertIsNone(check_scene.overlay_path(None, 1, 0))


if __name__ == '__main__':
    unittest.main()
