#!/usr/bin/python3
"""Plots of a lisfm pipeline run (docs/FORMATS.md "Pipeline plots").

  /usr/bin/python3 scripts/pipeline_plots.py --output_dir D
      --trajectory NAME=PATH [--trajectory NAME=PATH ...]
      [--groundtruth PATH] [--model_path sparse/0]

Writes, each as a PNG written to a temporary name and renamed when complete:
  D/trajectories.png  top view (x-y, metres, equal axes) of every trajectory and
                      the ground truth; with --groundtruth each trajectory is
                      first SE(3)-aligned to it (the frames of lio / pose_slam
                      and of the simulator's ground truth differ).
  D/errors.png        (only with --groundtruth) position error (m) over time (s
                      since the ground truth's start) of each trajectory after
                      SE(3) alignment to the ground truth.
  D/model.png         (only with --model_path) top view of the COLMAP binary
                      model's 3D points coloured by track length (colour bar),
                      camera centres on top; axis limits from the 1-99
                      percentiles of the points and the camera centres.

Trajectories are TUM files (`t x y z qx qy qz qw`, t in seconds; '#' lines and
blank lines skipped). Alignment: each trajectory pose time is matched to the
ground truth position linearly interpolated at that time (times outside the
ground truth are left out), then the rigid transform minimising the squared
position differences (Umeyama 1991, no scale) is applied.

Prints per trajectory its pose count and position RMSE / max after alignment,
and the model's image, point and mean track-length counts.

Bad input (a missing or malformed file, a NAME=PATH without '=', no common
time with the ground truth) prints one `error: ...` line naming the file and
line and exits 1; bad options exit 2 (argparse). Needs numpy and matplotlib
(Debian python3-numpy, python3-matplotlib); without them: error, exit 1.
"""

import argparse
import os
import struct
import sys

try:
    import numpy as np
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.axes_grid1 import make_axes_locatable
except ImportError as e:  # pragma: no cover - depends on the machine
    sys.stderr.write(
        "error: pipeline_plots.py needs numpy and matplotlib (Debian python3-numpy "
        "python3-matplotlib; scripts/install_deps.sh installs them): %s\n" % e)
    sys.exit(1)


class InputError(Exception):
    pass


# COLMAP camera model id -> number of parameters (colmap/src/base/camera_models.h).
CAMERA_NUM_PARAMS = {0: 3, 1: 4, 2: 4, 3: 5, 4: 8, 5: 8, 6: 12, 7: 5, 8: 4, 9: 5, 10: 12}


def read_tum(path):
    """Returns (t [s], xyz [m]) arrays of a TUM file."""
    if not os.path.isfile(path):
        raise InputError("%s: file not found (TUM trajectory)" % path)
    times, positions = [], []
    with open(path) as f:
        for line_number, line in enumerate(f, 1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            cols = s.split()
            if len(cols) != 8:
                raise InputError("%s:line %d: expected 8 columns (t x y z qx qy qz qw), found %d"
                                 % (path, line_number, len(cols)))
            try:
                values = [float(c) for c in cols]
            except ValueError:
                raise InputError("%s:line %d: not a number in '%s'" % (path, line_number, s))
            if times and values[0] <= times[-1]:
                raise InputError("%s:line %d: time %.9f does not increase" %
                                 (path, line_number, values[0]))
            times.append(values[0])
            positions.append(values[1:4])
    if not times:
        raise InputError("%s: no poses (TUM trajectory)" % path)
    return np.array(times), np.array(positions)


class BinaryReader:
    def __init__(self, path):
        if not os.path.isfile(path):
            raise InputError("%s: file not found (COLMAP binary model)" % path)
        with open(path, "rb") as f:
            self.data = f.read()
        self.path = path
        self.offset = 0

    def read(self, fmt, what):
        size = struct.calcsize(fmt)
        if self.offset + size > len(self.data):
            raise InputError("%s: truncated at byte %d reading %s" % (self.path, self.offset, what))
        values = struct.unpack_from(fmt, self.data, self.offset)
        self.offset += size
        return values

    def skip(self, size, what):
        if self.offset + size > len(self.data):
            raise InputError("%s: truncated at byte %d reading %s" % (self.path, self.offset, what))
        self.offset += size

    def read_string(self, what):
        end = self.data.find(b"\0", self.offset)
        if end < 0:
            raise InputError("%s: truncated at byte %d reading %s" % (self.path, self.offset, what))
        s = self.data[self.offset:end].decode("utf-8", "replace")
        self.offset = end + 1
        return s


def quat_to_matrix(qw, qx, qy, qz):
    n = np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
    return np.array([
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
        [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
        [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)]])


def read_model(folder):
    """Returns (camera centres Nx3, points Mx3, track lengths M) of a COLMAP
    binary model (3.8 byte layout: cameras.bin, images.bin, points3D.bin)."""
    if not os.path.isdir(folder):
        raise InputError("%s: model folder not found" % folder)
    cameras = BinaryReader(os.path.join(folder, "cameras.bin"))
    (num_cameras,) = cameras.read("<Q", "camera count")
    for i in range(num_cameras):
        _, model_id, _, _ = cameras.read("<iiQQ", "camera %d" % i)
        if model_id not in CAMERA_NUM_PARAMS:
            raise InputError("%s: camera %d: unknown camera model id %d" %
                             (cameras.path, i, model_id))
        cameras.skip(8 * CAMERA_NUM_PARAMS[model_id], "camera %d parameters" % i)

    images = BinaryReader(os.path.join(folder, "images.bin"))
    (num_images,) = images.read("<Q", "image count")
    centres = []
    for i in range(num_images):
        values = images.read("<I7dI", "image %d" % i)
        qvec, tvec = values[1:5], np.array(values[5:8])
        images.read_string("image %d name" % i)
        (num_points2d,) = images.read("<Q", "image %d point count" % i)
        images.skip(24 * num_points2d, "image %d points" % i)
        centres.append(-quat_to_matrix(*qvec).T.dot(tvec))

    points = BinaryReader(os.path.join(folder, "points3D.bin"))
    (num_points,) = points.read("<Q", "point count")
    xyz = np.zeros((num_points, 3))
    track_lengths = np.zeros(num_points, dtype=int)
    for i in range(num_points):
        values = points.read("<Q3d3BdQ", "point %d" % i)
        xyz[i] = values[1:4]
        track_lengths[i] = values[8]
        points.skip(8 * values[8], "point %d track" % i)
    return np.array(centres).reshape(-1, 3), xyz, track_lengths


def umeyama_se3(source, target):
    """R, t minimising sum |target - (R source + t)|^2 (Umeyama 1991, scale 1)."""
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    covariance = (target - mu_t).T.dot(source - mu_s) / len(source)
    u, _, vt = np.linalg.svd(covariance)
    d = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        d[2, 2] = -1
    rotation = u.dot(d).dot(vt)
    return rotation, mu_t - rotation.dot(mu_s)


def align_to_groundtruth(name, path, times, positions, gt_times, gt_positions):
    """Returns (times, aligned positions, position errors) over the poses inside
    the ground truth's time span."""
    inside = (times >= gt_times[0]) & (times <= gt_times[-1])
    if inside.sum() < 3:
        raise InputError("%s: trajectory %s has %d poses within the ground truth's time span "
                         "(%.3f-%.3f s), need 3" % (path, name, inside.sum(), gt_times[0],
                                                   gt_times[-1]))
    t = times[inside]
    p = positions[inside]
    g = np.column_stack([np.interp(t, gt_times, gt_positions[:, k]) for k in range(3)])
    rotation, translation = umeyama_se3(p, g)
    aligned = p.dot(rotation.T) + translation
    return t, aligned, np.linalg.norm(aligned - g, axis=1)


def save(figure, path):
    tmp = path + ".tmp-%d.png" % os.getpid()
    figure.savefig(tmp, dpi=110, bbox_inches="tight")
    plt.close(figure)
    os.replace(tmp, path)


def plot_trajectories(output_dir, trajectories, groundtruth):
    figure, axis = plt.subplots(figsize=(8, 7))
    if groundtruth is not None:
        axis.plot(groundtruth[1][:, 0], groundtruth[1][:, 1], color="black", linewidth=2.5,
                  alpha=0.35, label="ground truth")
    for name, (_, positions) in trajectories:
        line, = axis.plot(positions[:, 0], positions[:, 1], linewidth=1.2, label=name)
        axis.plot(positions[0, 0], positions[0, 1], "o", color=line.get_color(), markersize=5)
    axis.plot([], [], "o", color="gray", markersize=5, label="start")
    axis.set_aspect("equal", adjustable="datalim")
    axis.set_xlabel("x [m]")
    axis.set_ylabel("y [m]")
    title = "Trajectories, top view"
    if groundtruth is not None:
        title += " (each SE(3)-aligned to the ground truth)"
    axis.set_title(title)
    axis.grid(True, alpha=0.3)
    axis.legend(loc="best")
    save(figure, os.path.join(output_dir, "trajectories.png"))


def plot_errors(output_dir, errors, t0):
    figure, axis = plt.subplots(figsize=(9, 4.5))
    for name, (times, error) in errors:
        rmse = np.sqrt(np.mean(error ** 2))
        axis.plot(times - t0, error, linewidth=1.2,
                  label="%s (RMSE %.3f m, max %.3f m)" % (name, rmse, error.max()))
    axis.set_xlabel("time since the ground truth's start [s]")
    axis.set_ylabel("position error [m]")
    axis.set_title("Position error against ground truth after SE(3) alignment")
    top = max([error.max() for _, (_, error) in errors] + [1e-6])
    axis.set_ylim(0, 1.35 * top)  # room for the legend above the curves
    axis.grid(True, alpha=0.3)
    axis.legend(loc="upper left")
    save(figure, os.path.join(output_dir, "errors.png"))


def plot_model(output_dir, model_path, centres, xyz, track_lengths):
    figure, axis = plt.subplots(figsize=(8, 7))
    if len(xyz):
        order = np.argsort(track_lengths)  # long tracks drawn last (on top)
        vmax = max(3, np.percentile(track_lengths, 99))
        scatter = axis.scatter(xyz[order, 0], xyz[order, 1], c=track_lengths[order], s=3,
                               cmap="viridis", vmin=2, vmax=vmax, linewidths=0)
        # A colour bar axis as tall as the (equal-aspect) plot.
        bar_axis = make_axes_locatable(axis).append_axes("right", size="4%", pad=0.1)
        bar = figure.colorbar(scatter, cax=bar_axis)
        bar.set_label("track length (images per point)")
    if len(centres):
        axis.scatter(centres[:, 0], centres[:, 1], s=10, color="red", marker="^",
                     label="camera centres (%d images)" % len(centres), zorder=3)
        axis.legend(loc="upper right")
    extent = [c for c in (xyz, centres) if len(c)]
    if extent:
        pts = np.vstack(extent)
        lo = np.percentile(xyz[:, :2], 1, axis=0) if len(xyz) else pts[:, :2].min(axis=0)
        hi = np.percentile(xyz[:, :2], 99, axis=0) if len(xyz) else pts[:, :2].max(axis=0)
        if len(centres):
            lo = np.minimum(lo, centres[:, :2].min(axis=0))
            hi = np.maximum(hi, centres[:, :2].max(axis=0))
        margin = 0.05 * max(hi[0] - lo[0], hi[1] - lo[1], 1e-3)
        axis.set_xlim(lo[0] - margin, hi[0] + margin)
        axis.set_ylim(lo[1] - margin, hi[1] + margin)
    axis.set_aspect("equal", adjustable="box")
    axis.set_xlabel("x [m]")
    axis.set_ylabel("y [m]")
    axis.set_title("Sparse model %s, top view: %d points, %d images" %
                   (os.path.join(*os.path.normpath(model_path).split(os.sep)[-2:]), len(xyz),
                    len(centres)))
    axis.grid(True, alpha=0.3)
    save(figure, os.path.join(output_dir, "model.png"))


def main():
    parser = argparse.ArgumentParser(
        description="Plots of a lisfm pipeline run: trajectories.png, errors.png, model.png")
    parser.add_argument("--output_dir", required=True, help="folder for the PNGs (created)")
    parser.add_argument("--trajectory", action="append", default=[], metavar="NAME=PATH",
                        help="a TUM trajectory to plot (repeatable)")
    parser.add_argument("--groundtruth", help="ground-truth TUM trajectory")
    parser.add_argument("--model_path", help="COLMAP binary model folder (e.g. sparse/0)")
    args = parser.parse_args()
    if not args.trajectory and not args.model_path:
        parser.error("nothing to plot: give --trajectory NAME=PATH and/or --model_path")

    try:
        trajectories = []
        for spec in args.trajectory:
            name, sep, path = spec.partition("=")
            if not sep or not name or not path:
                raise InputError("--trajectory %s: expected NAME=PATH" % spec)
            trajectories.append((name, path, read_tum(path)))
        groundtruth = read_tum(args.groundtruth) if args.groundtruth else None
        model = read_model(args.model_path) if args.model_path else None

        os.makedirs(args.output_dir, exist_ok=True)
        written = []
        if trajectories:
            shown, errors = [], []
            for name, path, (times, positions) in trajectories:
                if groundtruth is None:
                    shown.append((name, (times, positions)))
                    continue
                t, aligned, error = align_to_groundtruth(name, path, times, positions,
                                                         *groundtruth)
                shown.append((name, (t, aligned)))
                errors.append((name, (t, error)))
                print("pipeline_plots: %s: %d poses, position error after SE(3) alignment: "
                      "RMSE %.6f m, max %.6f m" % (name, len(t), np.sqrt(np.mean(error ** 2)),
                                                   error.max()))
            plot_trajectories(args.output_dir, shown, groundtruth)
            written.append("trajectories.png")
            if groundtruth is not None:
                plot_errors(args.output_dir, errors, groundtruth[0][0])
                written.append("errors.png")
        if model is not None:
            print("pipeline_plots: model %s: %d images, %d points, mean track length %.3f" %
                  (args.model_path, len(model[0]), len(model[1]),
                   model[2].mean() if len(model[2]) else 0.0))
            plot_model(args.output_dir, args.model_path, *model)
            written.append("model.png")
    except InputError as e:
        sys.stderr.write("error: %s\n" % e)
        return 1
    except OSError as e:
        sys.stderr.write("error: %s\n" % e)
        return 1
    print("pipeline_plots: wrote %s in %s" % (", ".join(written), args.output_dir))
    return 0


if __name__ == "__main__":
    sys.exit(main())
