"""The depth-sensor model (world/depth_sensor.py) against known answers: its axial noise,
its seeding, its calibration error; and the depth filter on a plane it must keep."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.sensors import CameraInfo

from drake_symplan.perception.depth_filter import DepthFilter, local_plane_depth
from drake_symplan.world.cameras import CameraConfig, back_project
from drake_symplan.world.depth_sensor import (
    CAMERA_NOISE,
    CameraNoise,
    calibration_error,
    camera_noise,
    sense,
    standard_normal,
)
from drake_symplan.world.scenes import ObjectSpec, Scene

CAMERA = CameraConfig()
INFO = CameraInfo(CAMERA.width, CAMERA.height, np.radians(CAMERA.fov_y_deg))
FOCAL, CENTRE = INFO.focal_x(), (INFO.center_x(), INFO.center_y())
FLAT = np.ones((CAMERA.height, CAMERA.width), np.float32)  # a wall facing the camera


@pytest.mark.parametrize("depth", [1.0, 1.5])
def test_axial_noise_follows_the_d400_formula(depth):
    # Intel's RMS error: depth^2 * subpixel / (focal_px * baseline); 1 mm steps add
    # 0.3 mm in quadrature, which the 10 % allows.
    noise = CAMERA_NOISE["realsense"]
    image = sense(FLAT * depth, FOCAL, CENTRE, noise, np.random.default_rng(0))[0]
    expected = depth ** 2 * 0.08 / (FOCAL * 0.050)
    measured = np.nanstd(image)
    assert abs(measured - expected) < 0.1 * expected, (measured, expected)
    assert abs(np.nanmean(image) - depth) < 1e-3
    assert np.isnan(image).mean() < 0.01  # a wall facing the camera has no holes


def test_heavy_doubles_every_term():
    assert CAMERA_NOISE["heavy"] == CAMERA_NOISE["realsense"].scaled(2.0)
    assert CAMERA_NOISE["heavy"].axial_sigma(1.0, FOCAL) == pytest.approx(
        2 * CAMERA_NOISE["realsense"].axial_sigma(1.0, FOCAL))
    assert not CAMERA_NOISE["none"].active and CAMERA_NOISE["realsense"].active
    with pytest.raises(ValueError, match="unknown camera noise 'loud'"):
        camera_noise("loud")


def _step_image():
    """A box's top 10 cm in front of a wall: depth edges, flying pixels, holes."""
    d = FLAT * 1.2
    d[200:300, 250:400] = 1.1
    return d


def test_a_seed_gives_the_same_images_and_another_seed_others():
    noise = CAMERA_NOISE["realsense"]
    a, b, c = (sense(_step_image(), FOCAL, CENTRE, noise, np.random.default_rng(s), frames=2)
               for s in (5, 5, 6))
    assert np.array_equal(a, b, equal_nan=True)
    assert not np.array_equal(a, c, equal_nan=True)
    assert not np.array_equal(a[0], a[1], equal_nan=True)  # each frame its own noise


def test_depth_edges_get_holes_and_flying_pixels():
    noise = CameraNoise(edge_missing=0.3, flying=0.15)
    image = sense(_step_image(), FOCAL, CENTRE, noise, np.random.default_rng(1))[0]
    edge = np.zeros(image.shape, bool)
    edge[199:301, 249:401] = True
    edge[201:299, 251:399] = False
    assert 0.2 < np.isnan(image[edge]).mean() < 0.4
    between = (image > 1.101) & (image < 1.199)
    assert between[edge].mean() > 0.05 and not between[~edge].any()


def test_calibration_error_has_the_set_size():
    noise = CameraNoise(calib_translation=0.003, calib_rotation_deg=0.5)
    X = calibration_error(noise, np.random.default_rng(2))
    assert np.linalg.norm(X.translation()) == pytest.approx(0.003)
    angle = np.arccos((np.trace(X.rotation().matrix()) - 1) / 2)
    assert np.degrees(angle) == pytest.approx(0.5)


def test_a_calibration_error_shifts_the_cloud_by_its_amount(camera_station):
    camera_station.reset(Scene([ObjectSpec("a", "cube", [0.7, 0.0, 0.025], 0.0)]))
    cam = camera_station.cameras[0]
    depth = camera_station.depth_frames()[0][0]
    before = back_project(cam, depth)
    shift = np.array([0.004, -0.002, 0.001])  # in the camera's frame
    try:
        cam.miscalibrate(RigidTransform(shift))
        moved = back_project(cam, depth)
        cam.miscalibrate(RigidTransform(RollPitchYaw(0.0, 0.0, np.radians(0.5)), [0, 0, 0]))
        turned = back_project(cam, depth)
    finally:
        cam.miscalibrate(RigidTransform())
    expected = cam.X_WC.rotation().matrix() @ shift
    assert np.allclose(moved - before, expected, atol=1e-9)
    assert np.linalg.norm(expected) == pytest.approx(np.linalg.norm(shift))
    # A turn about the optical axis moves each point along a chord of its circle round it.
    radial = np.linalg.norm(np.cross(before - cam.X_WC.translation(),
                                     cam.X_WC.rotation().matrix()[:, 2]), axis=1)
    assert np.allclose(np.linalg.norm(turned - before, axis=1), 2 * radial * np.sin(np.radians(0.25)),
                       rtol=1e-6)
    assert np.array_equal(back_project(cam, depth), before)  # put back


def test_the_station_draws_each_cameras_calibration_from_its_seed():
    from drake_symplan.world.cameras import default_cameras
    from drake_symplan.world.station import Station, StationConfig

    noise = CAMERA_NOISE["realsense"]
    station = Station(StationConfig(cameras=default_cameras(), camera_noise="realsense",
                                    camera_seed=4, pool_cubes=1, pool_longs=1))
    rng = np.random.default_rng([4, 0])
    for cam in station.cameras:
        error = cam.X_WC.inverse() @ cam.X_WB
        assert np.allclose(error.GetAsMatrix4(), calibration_error(noise, rng).GetAsMatrix4())
        assert np.linalg.norm(error.translation()) == pytest.approx(noise.calib_translation)


def test_the_filter_keeps_a_slanted_plane_and_drops_what_flies_off_it():
    # A plane seen at 50 degrees incidence, 1.2 m away, with 2 mm noise and a few pixels
    # flying 3 cm behind it: the fit brings the noise down and drops those pixels.
    v = np.mgrid[0:120, 0:160][0]
    y = (v - 60) / FOCAL  # the plane n . p = c with n = (0, sin 50, cos 50): depth c / n . ray
    tilt = np.radians(50)
    truth = 1.2 * np.cos(tilt) / (np.sin(tilt) * y + np.cos(tilt))
    rng = np.random.default_rng(3)
    noisy = truth + rng.normal(0, 0.002, truth.shape)
    flying = rng.random(truth.shape) < 0.02
    noisy[flying] += 0.03
    out, sigma = local_plane_depth(noisy, np.full(truth.shape, 0.002), DepthFilter())
    inner = np.s_[2:-2, 2:-2]
    assert np.isnan(out[flying]).all()
    kept = ~flying & np.isfinite(out)
    assert kept[inner].mean() > 0.95
    assert np.std((out - truth)[inner][kept[inner]]) < 0.0007
    assert np.median(sigma[inner]) == pytest.approx(0.002 / 5)  # 25 pixels fitted


def test_a_scene_is_seen_with_the_same_noise_whatever_came_before():
    from drake_symplan.world.cameras import default_cameras
    from drake_symplan.world.scenes import ObjectSpec, Scene
    from drake_symplan.world.station import Station, StationConfig

    station = Station(StationConfig(cameras=default_cameras(), camera_noise="realsense"))
    a = Scene([ObjectSpec("a", "cube", [0.7, 0.0, 0.025])])
    b = Scene([ObjectSpec("b", "long", [0.6, 0.1, 0.025])])
    station.reset(a)
    first = station.depth_frames(1)[0][0]
    station.reset(b)
    station.depth_frames(1)
    station.reset(a)  # after other frames of another scene: the same noise again
    assert np.array_equal(station.depth_frames(1)[0][0], first, equal_nan=True)


def test_the_sensors_normals_are_standard_normal():
    # Box-Muller in float32 (world/depth_sensor.standard_normal): moments, tails, and the
    # two halves of a buffer (one pair's cosine and sine) uncorrelated; an odd size too.
    rng = np.random.default_rng(9)
    z = np.concatenate([standard_normal(rng, np.empty(100_001, np.float32)) for _ in range(20)])
    z = z.astype(float)
    assert abs(z.mean()) < 0.003 and abs(z.std() - 1) < 0.003
    assert np.mean(np.abs(z) > 2) == pytest.approx(0.0455, abs=0.0015)
    assert np.mean(np.abs(z) > 3) == pytest.approx(0.0027, abs=0.0004)
    half = 50_001
    assert abs(np.corrcoef(z[:half - 1], z[half:2 * half - 1])[0, 1]) < 0.015
    assert np.isfinite(z).all()


def test_labels_are_read_only_where_a_surface_is_dark():
    # The UR10's black parts lose returns; the hand back-end has nothing dark, so its
    # station renders no label images (reflectance None) and loses no return for darkness.
    from drake_symplan.world.cameras import default_cameras
    from drake_symplan.world.depth_sensor import DARK_BELOW
    from drake_symplan.world.station import Station, StationConfig

    def table(robot):
        return Station(StationConfig(cameras=default_cameras()[:1], camera_noise="realsense",
                                     robot=robot, pool_cubes=1, pool_longs=1)).reflectance

    assert table("hand") is None
    assert table("ur10").min() < DARK_BELOW
