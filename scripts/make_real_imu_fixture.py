#!/usr/bin/env python3
"""Writes tests/fixtures/real_imu/ from two public recordings that no one on this project made
(see tests/fixtures/real_imu/README.md for sources, licences and what each file is):

- euroc_imu_april/: the EuRoC calibration sequence `imu_april` (ASL, ETH Zurich; VI-Sensor,
  hardware-synchronised stereo camera + ADIS16448 IMU, a 6x6 Kalibr aprilgrid), as kept in the
  test data of chutsu/yac (MIT): the AprilGrid corners detected in every cam0 image and the
  IMU samples. The camera side becomes a TUM pose file `T_world_cam0` (board frame as world)
  with dvlcal's covariance table beside it, solved here by PnP with EuRoC's published cam0
  intrinsics; the corners are kept too, so the poses can be solved again another way.
- mocap2gt_imu_mocap/: the real IMU + motion-capture recording in the estimator test data of
  zichao-shu/mocap2gt (Apache-2.0), with that tool's published IMU-to-marker calibration.

Usage (numpy only; nothing is downloaded):

    git -C /path/to/yac archive 3f326b5874fdd5134b8fe238b11bf7264f0c4ab0 \\
        yac/tests/test_data/calib/imu_april LICENSE | tar -x -C /tmp/yac
    git -C /path/to/mocap2gt archive 797f302bf406924c85e756a45b16c82d84e0d06c \\
        resource/estimator_test_data LICENCE | tar -x -C /tmp/m2g
    python3 scripts/make_real_imu_fixture.py --yac /tmp/yac --mocap2gt /tmp/m2g

The originals are checked against the SHA-256 digests below before anything is written.
Everything written is deterministic.
"""

import argparse
import hashlib
import math
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "fixtures" / "real_imu"

YAC_COMMIT = "3f326b5874fdd5134b8fe238b11bf7264f0c4ab0"
YAC_DIR = "yac/tests/test_data/calib/imu_april"
MOCAP2GT_COMMIT = "797f302bf406924c85e756a45b16c82d84e0d06c"
M2G_DIR = "resource/estimator_test_data"

# SHA-256 of the originals. A folder's digest is that of the `sha256sum` lines of its files
# ("<hex>  <relative path>\n"), sorted by path, as docs/formats.md defines for dvlcal's inputs.
ORIGINALS = {
    f"{YAC_DIR}/imu0.csv": "1b243659498c3343bdceb0c42062d5e575203624721c72479d22faa0777c9f56",
    f"{YAC_DIR}/cam0": "9b6bfa2c26ebcbb8dc3480605a287fd310c792057fcdf168c2ca56502772dd4d",
    f"{YAC_DIR}/config.yaml": "ac6f8b0aa507456e82f3cb645c05f93d6ae60bea0548cdc53f26eca83cc09b3f",
    f"{M2G_DIR}/imu_data.txt": "b6be8d9e6a1b2391c45ebce911d1850fe70839cc21bd8f7a77438d92c1fc5f8b",
    f"{M2G_DIR}/mocap_data.txt": "765052bdca26d1518e70b5179bb90e6115b6c0f08530c9383b46e2ad7ed672b9",
    f"{M2G_DIR}/mocap2gt_calib.yaml": "5bca40c8892d938303665d90c0d7a39049e07104a377e9c6c4fa9a2aa69e4998",
    f"{M2G_DIR}/estimator_config.yaml": "dec194d61c4b93b825bb3dca06b40becd718862c9734de3a6eb5b041d01b2131",
}

# ---------------------------------------------------------------------------------------------
# EuRoC's published calibration (mav0/cam0/sensor.yaml and mav0/imu0/sensor.yaml of every EuRoC
# sequence; the body frame B is the IMU frame: imu0's T_BS is the identity).

EUROC_T_B_CAM0 = np.array([
    [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975],
    [0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768],
    [-0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949],
    [0.0, 0.0, 0.0, 1.0],
])
EUROC_T_B_CAM1 = np.array([
    [0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556],
    [0.999598781151, 0.0130119051815, 0.0251588363115, 0.0453689425024],
    [-0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038],
    [0.0, 0.0, 0.0, 1.0],
])
EUROC_CAM0 = dict(
    intrinsics=[458.654, 457.296, 367.215, 248.375],
    distortion=[-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05],
    resolution=[752, 480],
)
EUROC_CAM1 = dict(
    intrinsics=[457.587, 456.134, 379.999, 255.238],
    distortion=[-0.28368365, 0.07451284, -0.00010473, -3.555e-05],
    resolution=[752, 480],
)
EUROC_IMU = dict(
    gyroscope_noise_density=1.6968e-04,
    gyroscope_random_walk=1.9393e-05,
    accelerometer_noise_density=2.0000e-3,
    accelerometer_random_walk=3.0000e-3,
    update_rate=200.0,
)
# Basalt's own calibration of the same rig from EuRoC's calibration sequences
# (VladyslavUsenko/basalt, data/euroc_ds_calib.json, double-sphere camera model): T_imu_cam0.
BASALT_EUROC_T_I_C0 = dict(
    p=[-0.016774788924641534, -0.068938940687127, 0.005139123188382424],
    q_xyzw=[-0.007239825785317818, 0.007541278561558601, 0.7017845426564943, 0.7123125505904486],
)

EUROC_IMU_HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
                    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")

# ---------------------------------------------------------------------------------------------
# Small geometry helpers (numpy only).


def hat(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def so3_exp(phi):
    th = np.linalg.norm(phi)
    if th < 1e-12:
        return np.eye(3) + hat(phi)
    k = phi / th
    K = hat(k)
    return np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K


def so3_log(R):
    c = max(-1.0, min(1.0, (np.trace(R) - 1) / 2))
    th = math.acos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-9:
        return 0.5 * w
    if th > math.pi - 1e-6:
        # near pi: from the symmetric part
        B = (R + np.eye(3)) / 2
        i = int(np.argmax(np.diag(B)))
        v = B[:, i] / math.sqrt(B[i, i])
        return th * v
    return th / (2 * math.sin(th)) * w


def left_jacobian(phi):
    th = np.linalg.norm(phi)
    K = hat(phi)
    if th < 1e-9:
        return np.eye(3) + 0.5 * K
    return (np.eye(3) + (1 - math.cos(th)) / th**2 * K + (th - math.sin(th)) / th**3 * K @ K)


def se3_exp(xi):
    """xi = [rho; phi] (dvlcal's order): R = exp(phi), t = J_l(phi) rho."""
    T = np.eye(4)
    T[:3, :3] = so3_exp(xi[3:])
    T[:3, 3] = left_jacobian(xi[3:]) @ xi[:3]
    return T


def inv_T(T):
    Ti = np.eye(4)
    Ti[:3, :3] = T[:3, :3].T
    Ti[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return Ti


def rot_to_quat_xyzw(R):
    """Hamilton quaternion [x, y, z, w] with w >= 0."""
    tr = np.trace(R)
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        w, x, y, z = 0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        w, x, y, z = (R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        w, x, y, z = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        w, x, y, z = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s
    q = np.array([x, y, z, w])
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def quat_xyzw_to_rot(q):
    x, y, z, w = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def angle_deg(Ra, Rb):
    return math.degrees(np.linalg.norm(so3_log(Ra.T @ Rb)))


# ---------------------------------------------------------------------------------------------
# Pinhole + radial-tangential (Kalibr's radtan, OpenCV's k1 k2 p1 p2).


def distort(xn, d):
    k1, k2, p1, p2 = d
    x, y = xn[:, 0], xn[:, 1]
    r2 = x * x + y * y
    rad = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], axis=1)


def undistort(xd, d, iters=30):
    x = xd.copy()
    for _ in range(iters):
        x = x - (distort(x, d) - xd) * 1.0
    return x


def project(Pc, cam):
    fu, fv, pu, pv = cam["intrinsics"]
    xn = Pc[:, :2] / Pc[:, 2:3]
    xd = distort(xn, cam["distortion"])
    return np.stack([fu * xd[:, 0] + pu, fv * xd[:, 1] + pv], axis=1)


# ---------------------------------------------------------------------------------------------
# PnP: pose T_world_cam (board = world) from board points and pixels, covariance of the right
# perturbation [rho; phi] (dvlcal's convention), outlier tags dropped as dvlcal's detect does.


def homography_pose(Pw, uv, cam):
    fu, fv, pu, pv = cam["intrinsics"]
    xd = np.stack([(uv[:, 0] - pu) / fu, (uv[:, 1] - pv) / fv], axis=1)
    xn = undistort(xd, cam["distortion"])
    A = []
    for (X, Y), (x, y) in zip(Pw[:, :2], xn):
        A.append([X, Y, 1, 0, 0, 0, -x * X, -x * Y, -x])
        A.append([0, 0, 0, X, Y, 1, -y * X, -y * Y, -y])
    _, _, Vt = np.linalg.svd(np.asarray(A))
    H = Vt[-1].reshape(3, 3)
    if H[2, 2] < 0:
        H = -H
    h1, h2, h3 = H[:, 0], H[:, 1], H[:, 2]
    s = 2.0 / (np.linalg.norm(h1) + np.linalg.norm(h2))
    r1, r2, t = h1 * s, h2 * s, h3 * s
    if t[2] < 0:
        r1, r2, t = -r1, -r2, -t
    R = np.stack([r1, r2, np.cross(r1, r2)], axis=1)
    U, _, Vt = np.linalg.svd(R)
    R = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    T_cam_world = np.eye(4)
    T_cam_world[:3, :3] = R
    T_cam_world[:3, 3] = t
    return inv_T(T_cam_world)


def residuals(T_world_cam, Pw, uv, cam):
    T_cw = inv_T(T_world_cam)
    Pc = Pw @ T_cw[:3, :3].T + T_cw[:3, 3]
    return (project(Pc, cam) - uv).ravel()


def jacobian(T, Pw, uv, cam, h=1e-7):
    J = np.zeros((2 * len(Pw), 6))
    for k in range(6):
        d = np.zeros(6)
        d[k] = h
        rp = residuals(T @ se3_exp(d), Pw, uv, cam)
        rm = residuals(T @ se3_exp(-d), Pw, uv, cam)
        J[:, k] = (rp - rm) / (2 * h)
    return J


def refine(T, Pw, uv, cam, iters=30):
    lam = 1e-3
    r = residuals(T, Pw, uv, cam)
    cost = r @ r
    for _ in range(iters):
        J = jacobian(T, Pw, uv, cam)
        A = J.T @ J
        g = J.T @ r
        while True:
            delta = -np.linalg.solve(A + lam * np.diag(np.diag(A)), g)
            Tn = T @ se3_exp(delta)
            rn = residuals(Tn, Pw, uv, cam)
            cn = rn @ rn
            if cn <= cost:
                T, r, cost = Tn, rn, cn
                lam = max(lam / 10, 1e-9)
                break
            lam *= 10
            if lam > 1e8:
                return T
        if np.linalg.norm(delta) < 1e-12:
            break
    return T


def solve_frame(obs, cam, min_corners=8, reject_factor=3.0, reject_min_px=1.0, min_sigma=0.02):
    """obs: list of (tag_id, Pw (4x3), uv (4x2)). Returns dict or None."""
    used = list(obs)
    rejected = 0
    while True:
        if 4 * len(used) < min_corners:
            return None
        Pw = np.concatenate([o[1] for o in used])
        uv = np.concatenate([o[2] for o in used])
        T = refine(homography_pose(Pw, uv, cam), Pw, uv, cam)
        r = residuals(T, Pw, uv, cam).reshape(-1, 4, 2)
        tag_rms = np.sqrt((r**2).sum(axis=2).mean(axis=1))
        worst = int(np.argmax(tag_rms))
        thr = max(reject_min_px, reject_factor * float(np.median(tag_rms)))
        if tag_rms[worst] > thr:
            used.pop(worst)
            rejected += 1
            continue
        m = r.size
        ssr = float((r**2).sum())
        sigma = max(min_sigma, math.sqrt(ssr / (m - 6)))
        J = jacobian(T, Pw, uv, cam)
        cov = sigma**2 * np.linalg.inv(J.T @ J)
        cov = 0.5 * (cov + cov.T)
        rms = math.sqrt(ssr / (m / 2))
        return dict(T=T, cov=cov, tags=len(used), corners=4 * len(used), rms=rms,
                    rejected=rejected, sigma=sigma)


# ---------------------------------------------------------------------------------------------
# Files.


def sha256_file(p):
    return hashlib.sha256(Path(p).read_bytes()).hexdigest()


def sha256_folder(p):
    p = Path(p)
    lines = []
    for f in sorted((x for x in p.rglob("*") if x.is_file()), key=lambda x: str(x.relative_to(p)).encode()):
        lines.append(f"{sha256_file(f)}  {f.relative_to(p)}\n")
    return hashlib.sha256("".join(lines).encode()).hexdigest(), len(lines)


def digest(p):
    p = Path(p)
    return sha256_folder(p)[0] if p.is_dir() else sha256_file(p)


def ns_to_s(ns):
    """Exact decimal seconds with nine decimals from integer nanoseconds."""
    ns = int(ns)
    return f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}"


def g(x):
    """Shortest repr that reads back to the same double."""
    return repr(float(x))


def mat_yaml(T, indent="  "):
    rows = []
    for row in T:
        rows.append(indent + "- [" + ", ".join(g(v) for v in row) + "]")
    return "\n".join(rows)


def write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


# ---------------------------------------------------------------------------------------------
# Fixture 1: EuRoC imu_april.


def read_grid_csv(path):
    """yac's aprilgrid CSV: ts,tag_rows,tag_cols,tag_size,tag_spacing,kp_x,kp_y,p_x,p_y,p_z,
    tag_id,corner_idx (one row per detected corner; a header line only when nothing was seen).
    Returns {tag_id: (Pw 4x3, uv 4x2)} of the tags with all four corners, keeping the text of
    the pixel coordinates too."""
    tags = {}
    for line in Path(path).read_text().splitlines()[1:]:
        f = line.split(",")
        if len(f) != 12:
            continue
        tid, ci = int(f[10]), int(f[11])
        tags.setdefault(tid, {})[ci] = (float(f[7]), float(f[8]), float(f[9]), float(f[5]), float(f[6]))
    out = {}
    for tid, cs in sorted(tags.items()):
        if sorted(cs) != [0, 1, 2, 3]:
            continue
        Pw = np.array([cs[i][:3] for i in range(4)])
        uv = np.array([cs[i][3:] for i in range(4)])
        out[tid] = (Pw, uv)
    return out


def board_corners(tid, rows=6, cols=6, size=0.088, spacing=0.3):
    r, c = divmod(tid, cols)
    step = size * (1 + spacing)
    x0, y0 = c * step, r * step
    return np.array([[x0, y0, 0], [x0 + size, y0, 0], [x0 + size, y0 + size, 0], [x0, y0 + size, 0]])


def make_euroc(yac_root, out):
    src = Path(yac_root) / YAC_DIR
    cam = EUROC_CAM0
    files = sorted((src / "cam0").glob("*.csv"), key=lambda p: int(p.stem))
    tum, table, corners = [], [], []
    n_frames, n_empty, n_failed = len(files), 0, 0
    max_board_err = 0.0
    for f in files:
        t_ns = int(f.stem)
        tags = read_grid_csv(f)
        if not tags:
            n_empty += 1
            continue
        obs = []
        for tid, (Pw, uv) in tags.items():
            max_board_err = max(max_board_err, float(np.abs(Pw - board_corners(tid)).max()))
            obs.append((tid, board_corners(tid), uv))
            corners.append(f"{t_ns},{tid}," + ",".join(f"{v:.3f}" for v in uv.ravel()))
        sol = solve_frame(obs, cam)
        if sol is None:
            n_failed += 1
            continue
        T = sol["T"]
        q = rot_to_quat_xyzw(T[:3, :3])
        tum.append(f"{ns_to_s(t_ns)} " + " ".join(g(v) for v in T[:3, 3]) + " " + " ".join(g(v) for v in q))
        c = sol["cov"]
        vals = [c[i, j] for i in range(6) for j in range(i, 6)]
        table.append(f"{ns_to_s(t_ns)},{sol['tags']},{sol['corners']},{g(sol['rms'])},{sol['rejected']},"
                     f"{g(sol['sigma'])}," + ",".join(g(v) for v in vals))
    assert max_board_err < 1e-9, f"yac's board points differ from the Kalibr grid by {max_board_err}"

    d = out / "euroc_imu_april"
    write(d / "cam0_poses.txt",
          "# T_world_cam0 (world = the aprilgrid's board frame), TUM: t tx ty tz qx qy qz qw\n"
          "# solved by scripts/make_real_imu_fixture.py from the corners in detections/\n"
          + "\n".join(tum) + "\n")
    header = "t,tags,corners,rms_px,rejected,sigma_px," + ",".join(f"c{i}{j}" for i in range(6) for j in range(i, 6))
    write(d / "cam0_poses.txt.frames.csv",
          "# one row per pose of the TUM file: time (s), tag observations used (a tag in both "
          "cameras counts twice), corners used, reprojection RMS (px), observations rejected, "
          "pixel sigma used for the covariance, then the 21 upper-triangle values (row by row) of "
          "the 6x6 covariance of the right perturbation [rho; phi] of T_world_cam0 (m, rad)\n"
          + header + "\n" + "\n".join(table) + "\n")
    write(d / "detections" / "cam0_corners.csv",
          "# AprilGrid corners detected in cam0 (yac's detections, pixel coordinates rounded to 0.001 px):\n"
          "# time [ns], tag id, then u,v of corners 0..3 (bottom-left, bottom-right, top-right, top-left of the\n"
          "# tag's black square on the board; board geometry in ../april_6x6.yaml)\n"
          "#timestamp [ns],tag_id,u0,v0,u1,v1,u2,v2,u3,v3\n" + "\n".join(corners) + "\n")

    # IMU: the values' text unchanged, EuRoC's header.
    lines = (src / "imu0.csv").read_text().splitlines()
    assert lines[0].startswith("#ts,wx,wy,wz,ax,ay,az"), lines[0]
    imu_rows = [l for l in lines[1:] if l.strip()]
    write(d / "imu0" / "data.csv", EUROC_IMU_HEADER + "\n" + "\n".join(imu_rows) + "\n")
    imu_t = np.array([int(l.split(",")[0]) for l in imu_rows])

    write(d / "imu.yaml",
          "# EuRoC's published IMU noise (mav0/imu0/sensor.yaml: ADIS16448), in Kalibr's imu.yaml keys.\n"
          f"accelerometer_noise_density: {EUROC_IMU['accelerometer_noise_density']}   # m/s^2/sqrt(Hz)\n"
          f"accelerometer_random_walk: {EUROC_IMU['accelerometer_random_walk']}     # m/s^3/sqrt(Hz)\n"
          f"gyroscope_noise_density: {EUROC_IMU['gyroscope_noise_density']}     # rad/s/sqrt(Hz)\n"
          f"gyroscope_random_walk: {EUROC_IMU['gyroscope_random_walk']}       # rad/s^2/sqrt(Hz)\n"
          f"update_rate: {EUROC_IMU['update_rate']}\n"
          "rostopic: /imu0\n")
    T_c1_c0 = inv_T(EUROC_T_B_CAM1) @ EUROC_T_B_CAM0
    write(d / "camchain.yaml",
          "# EuRoC's published camera calibration (mav0/cam0/sensor.yaml, mav0/cam1/sensor.yaml), Kalibr camchain form.\n"
          "# The poses in cam0_poses.txt were solved with cam0 alone. cam1's T_cn_cnm1 = inv(T_B_cam1) T_B_cam0.\n"
          "cam0:\n  camera_model: pinhole\n"
          f"  intrinsics: {EUROC_CAM0['intrinsics']}\n  distortion_model: radtan\n"
          f"  distortion_coeffs: {EUROC_CAM0['distortion']}\n  resolution: {EUROC_CAM0['resolution']}\n"
          "  rostopic: /cam0/image_raw\n"
          "cam1:\n  camera_model: pinhole\n"
          f"  intrinsics: {EUROC_CAM1['intrinsics']}\n  distortion_model: radtan\n"
          f"  distortion_coeffs: {EUROC_CAM1['distortion']}\n  resolution: {EUROC_CAM1['resolution']}\n"
          "  rostopic: /cam1/image_raw\n"
          "  T_cn_cnm1:\n" + mat_yaml(T_c1_c0, "  ") + "\n")
    write(d / "april_6x6.yaml",
          "# EuRoC's calibration target (the yac grid files state the same: 6x6, 0.088 m, spacing 0.3).\n"
          "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n")

    T_cam_imu = inv_T(EUROC_T_B_CAM0)
    Rb = quat_xyzw_to_rot(BASALT_EUROC_T_I_C0["q_xyzw"])
    basalt_T_i_c0 = np.eye(4)
    basalt_T_i_c0[:3, :3] = Rb
    basalt_T_i_c0[:3, 3] = BASALT_EUROC_T_I_C0["p"]
    basalt_T_c_i = inv_T(basalt_T_i_c0)
    d_rot = angle_deg(T_cam_imu[:3, :3], basalt_T_c_i[:3, :3])
    d_p = basalt_T_c_i[:3, 3] - T_cam_imu[:3, 3]
    q = rot_to_quat_xyzw(T_cam_imu[:3, :3])
    write(d / "published.yaml",
          "# The published camera-IMU calibration of the EuRoC VI-Sensor (the rig of this recording).\n"
          "# Frames: cam = cam0 (OpenCV: x right, y down, z forward); imu = the ADIS16448's frame S,\n"
          "# which is EuRoC's body frame B (mav0/imu0/sensor.yaml: T_BS = identity).\n"
          "source: >-\n"
          "  EuRoC MAV dataset (Burri et al., IJRR 2016), mav0/cam0/sensor.yaml of every sequence:\n"
          "  T_BS of cam0, the pose of cam0 in the body (IMU) frame, i.e. T_imu_cam0 (maps cam0 points\n"
          "  into the IMU frame). Below is its inverse.\n"
          "# T_cam_imu maps IMU-frame points into cam0: p_cam = R_cam_imu p_imu + t_cam_imu (Kalibr's T_cam_imu).\n"
          "T_cam_imu:\n" + mat_yaml(T_cam_imu) + "\n"
          "# As published (row-major, 4x4): T_imu_cam = T_BS(cam0).\n"
          "T_imu_cam:\n" + mat_yaml(EUROC_T_B_CAM0) + "\n"
          f"quaternion_cam_imu_xyzw: [{', '.join(g(v) for v in q)}]\n"
          f"translation_cam_imu_m: [{', '.join(g(v) for v in T_cam_imu[:3, 3])}]\n"
          "# Clock: the VI-Sensor time-stamps camera and IMU in hardware on one clock; EuRoC publishes no\n"
          "# camera-IMU time shift (none in any sensor.yaml). Our convention: t_cam = t_imu + imu_time_offset_s.\n"
          "imu_time_offset_s: 0.0\n"
          "imu_time_offset_published: false   # 0 is the hardware-sync claim, not a published estimate\n"
          "# EuRoC states no tolerance. For scale: Basalt's independent calibration of the same rig from\n"
          "# EuRoC's calibration sequences (VladyslavUsenko/basalt data/euroc_ds_calib.json, T_imu_cam0,\n"
          "# double-sphere model) differs from EuRoC's by:\n"
          "tolerance: null\n"
          "independent_calibration_difference:\n"
          "  source: VladyslavUsenko/basalt data/euroc_ds_calib.json (T_imu_cam[0])\n"
          f"  rotation_deg: {d_rot:.4f}\n"
          f"  translation_cam_imu_m: [{', '.join(f'{v:.5f}' for v in d_p)}]   # Basalt minus EuRoC, cam0 frame\n"
          f"  translation_norm_m: {np.linalg.norm(d_p):.5f}\n")
    print(f"euroc_imu_april: {n_frames} frames, {len(tum)} posed, {n_empty} without tags, {n_failed} too few")
    print(f"  camera {ns_to_s(int(files[0].stem))} .. {ns_to_s(int(files[-1].stem))}, "
          f"imu {ns_to_s(imu_t[0])} .. {ns_to_s(imu_t[-1])} ({len(imu_t)} samples, "
          f"{(len(imu_t) - 1) / ((imu_t[-1] - imu_t[0]) * 1e-9):.3f} Hz)")
    print(f"  Basalt vs EuRoC: {d_rot:.4f} deg, {np.linalg.norm(d_p) * 1000:.2f} mm")
    return d


# ---------------------------------------------------------------------------------------------
# Fixture 2: mocap2gt's real IMU + motion-capture recording.


def make_mocap2gt(m2g_root, out):
    src = Path(m2g_root) / M2G_DIR
    d = out / "mocap2gt_imu_mocap"
    imu_lines = [l for l in (src / "imu_data.txt").read_text().splitlines() if l.strip()]
    rows = []
    for l in imu_lines:
        f = [x.strip() for x in l.split(",")]
        assert len(f) == 7, l
        int(f[0])
        rows.append(",".join(f))
    write(d / "imu0" / "data.csv", EUROC_IMU_HEADER + "\n" + "\n".join(rows) + "\n")
    imu_t = np.array([int(r.split(",")[0]) for r in rows])

    # calibration as published (mocap2gt_calib.yaml) and the noise of estimator_config.yaml
    calib = {}
    for l in (src / "mocap2gt_calib.yaml").read_text().splitlines():
        k, v = l.split(":", 1)
        v = v.strip()
        calib[k.strip()] = [float(x) for x in v.strip("[]").split(",")] if v.startswith("[") else float(v)
    cfg = {}
    for l in (src / "estimator_config.yaml").read_text().splitlines():
        s = l.split("#", 1)[0].strip()
        if ":" in s:
            k, v = s.split(":", 1)
            cfg[k.strip()] = v.strip()
    noise = [float(x) for x in cfg["imu_noise"].strip("[]").split(",")]
    rate = (len(imu_t) - 1) / ((imu_t[-1] - imu_t[0]) * 1e-9)

    # mocap poses: TUM already (t x y z qx qy qz qw, T_world_marker), mocap clock. Cropped to the
    # IMU's span (on the mocap clock, through the published offset) with 1 s to spare each side.
    toff = calib["toff_MI"]
    t0 = (imu_t[0] * 1e-9 - toff) - 1.0
    t1 = (imu_t[-1] * 1e-9 - toff) + 1.0
    mocap = []
    n_all = 0
    for l in (src / "mocap_data.txt").read_text().splitlines():
        if not l.strip():
            continue
        n_all += 1
        f = l.split(" ")
        assert len(f) == 8, l
        if t0 <= float(f[0]) <= t1:
            mocap.append(l)
    write(d / "marker_poses.txt",
          "# T_world_marker (motion-capture world frame W, rigid-body marker frame M), TUM: t tx ty tz qx qy qz qw\n"
          "# t: the motion-capture clock, seconds from its own zero (not Unix time). Values unchanged from mocap2gt.\n"
          + "\n".join(mocap) + "\n")

    write(d / "imu.yaml",
          "# The IMU noise mocap2gt's authors give for this recording (estimator_config.yaml: imu_noise,\n"
          "# continuous-time densities), in Kalibr's imu.yaml keys.\n"
          f"accelerometer_noise_density: {noise[0]}   # m/s^2/sqrt(Hz)\n"
          f"accelerometer_random_walk: {noise[1]}    # m/s^3/sqrt(Hz)\n"
          f"gyroscope_noise_density: {noise[2]}     # rad/s/sqrt(Hz)\n"
          f"gyroscope_random_walk: {noise[3]}      # rad/s^2/sqrt(Hz)\n"
          f"# The samples come at {rate:.1f} Hz (steps of 1.975 ms); estimator_config.yaml says imu_freq: {cfg['imu_freq']}.\n"
          f"update_rate: {rate:.1f}\n")

    R = quat_xyzw_to_rot(calib["q_MI"])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = calib["p_MI"]
    q = rot_to_quat_xyzw(R)
    # initial guess in estimator_config.yaml (commented out there): another estimate of the same
    p_init = [float(x) for x in "-0.006187066980904047, 0.044462231955122895, -0.051046700136109235".split(",")]
    q_init = [float(x) for x in "-0.5799490252444921, 0.41579825336693943, -0.44479680435002378, 0.54122707199009623".split(",")]
    d_rot = angle_deg(R, quat_xyzw_to_rot(q_init))
    d_p = np.array(p_init) - np.array(calib["p_MI"])
    write(d / "published.yaml",
          "# mocap2gt's published IMU-to-marker calibration of this recording (resource/estimator_test_data/\n"
          "# mocap2gt_calib.yaml, the output of its estimator on these very data; README: \"Calibration parameter\n"
          "# results\"). Frames: imu = the device's IMU frame I; marker = the motion-capture rigid body M.\n"
          "source: zichao-shu/mocap2gt resource/estimator_test_data/mocap2gt_calib.yaml (p_MI, q_MI [x y z w], toff_MI)\n"
          "# T_marker_imu = T_MI maps IMU-frame points into the marker frame: T_world_imu = T_world_marker T_marker_imu\n"
          "# (mocap2gt's residual: p_WM = p_WI - R_WI R_MI^T p_MI, R_WM = R_WI R_MI^T).\n"
          "T_marker_imu:\n" + mat_yaml(T) + "\n"
          f"quaternion_marker_imu_xyzw: [{', '.join(g(v) for v in q)}]\n"
          f"translation_marker_imu_m: [{', '.join(g(v) for v in calib['p_MI'])}]\n"
          f"# As published: p_MI {calib['p_MI']}, q_MI (xyzw) {calib['q_MI']} (the same rotation as q above, sign aside).\n"
          "# Gravity: q_WG, the rotation of mocap2gt's gravity-aligned frame G into the mocap world W:\n"
          f"quaternion_world_gravity_xyzw: [{', '.join(g(v) for v in calib['q_WG'])}]\n"
          "# Clock: mocap2gt's IMU time = mocap time + toff_MI. With the marker poses as the pose source\n"
          "# (the camera's place in our convention t_cam = t_imu + imu_time_offset_s):\n"
          f"imu_time_offset_s: {g(-toff)}\n"
          f"toff_MI_published_s: {g(toff)}\n"
          "# mocap2gt estimated a time offset that varies (control points every 30 s, variable_toff_flag: true)\n"
          "# and wrote only the first control point's value; the offset at other times is not published.\n"
          "tolerance: null\n"
          "# For scale: the initial guess left (commented out) in estimator_config.yaml differs from the result by\n"
          "initial_guess_difference:\n"
          f"  rotation_deg: {d_rot:.4f}\n"
          f"  translation_marker_imu_m: [{', '.join(f'{v:.5f}' for v in d_p)}]   # guess minus result\n")
    print(f"mocap2gt_imu_mocap: imu {len(imu_t)} samples {ns_to_s(imu_t[0])} .. {ns_to_s(imu_t[-1])} ({rate:.2f} Hz); "
          f"mocap {len(mocap)} of {n_all} poses kept, {mocap[0].split()[0]} .. {mocap[-1].split()[0]} s")
    return d


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--yac", required=True, help="root of chutsu/yac at the commit above (or its archive)")
    ap.add_argument("--mocap2gt", required=True, help="root of zichao-shu/mocap2gt at the commit above")
    ap.add_argument("--print-digests", action="store_true", help="print the originals' digests and stop")
    a = ap.parse_args()
    roots = {YAC_DIR: Path(a.yac), M2G_DIR: Path(a.mocap2gt)}
    bad = False
    for rel, want in ORIGINALS.items():
        base = roots[YAC_DIR] if rel.startswith(YAC_DIR) else roots[M2G_DIR]
        got = digest(base / rel)
        if a.print_digests:
            print(f"{rel}: {got}")
        elif got != want:
            print(f"{rel}: SHA-256 {got}, expected {want}", file=sys.stderr)
            bad = True
    if a.print_digests:
        return
    if bad:
        sys.exit("the originals differ from the ones the fixtures were made from")
    d1 = make_euroc(a.yac, OUT)
    d2 = make_mocap2gt(a.mocap2gt, OUT)
    # the licence texts the sources ask to be kept with copies of their files
    write(d1 / "LICENSE-MIT-yac", (Path(a.yac) / "LICENSE").read_text())
    write(d2 / "LICENSE-Apache-2.0-mocap2gt", (Path(a.mocap2gt) / "LICENCE").read_text())


if __name__ == "__main__":
    main()
