#!/usr/bin/python3
"""Bags written by Debian's python3-rosbag, for tests/e2e/bag_python_test.cc.

  bag_python_bags.py write DIR   writes DIR/hilti2022.bag and DIR/hilti2021.bag
  bag_python_bags.py check DIR   checks DIR/h22/ and DIR/h21/ (the folders `lisfm bag_importer`
                                 made of them) against the values written; exit 1 on a mismatch

HILTI 2022 (/hesai/pandar): x y z intensity float32, timestamp float64 (absolute s), ring uint16
in a padded layout (point_step 48, gaps between the fields, row_step with 16 bytes of row padding,
height 2: an organised cloud) with one NaN point (is_dense false); /alphasense/imu; two mono8 images
on /alphasense/cam0/image_raw.
HILTI 2021: /os_cloud_node/points big endian in the Ouster driver's layout (x y z, 4 bytes pad,
intensity float32, t uint32 ns since header.stamp, reflectivity uint16, ring uint8, ambient uint16,
range uint32; point_step 48); /livox/lidar livox_ros_driver/CustomMsg built with genpy from its
message definition (the package is not in Debian): timebase + offset_time (the earliest point 1 us
after timebase), points at the origin (no return) among them.
"""
import os
import struct
import sys

import numpy as np

T0_NS = 1646300000 * 10**9 + 123456789        # first IMU sample
N_IMU = 200                                   # 400 Hz, 0.5 s
SCANS = 3                                     # 10 Hz, from T0 + 50 ms
N_PTS = 100

LIVOX_MD5 = 'e4d6829bdfe657cb6c21a746c86b21a6'
LIVOX_DEF = """Header header
uint64 timebase
uint32 point_num
uint8  lidar_id
uint8[3]  rsvd
CustomPoint[] points

================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id

================================================================================
MSG: livox_ros_driver/CustomPoint
uint32 offset_time
float32 x
float32 y
float32 z
uint8 reflectivity
uint8 tag
uint8 line
"""


def imu_value(i):
    return ([0.01 * i, -0.02, 0.5 + 1e-3 * i], [0.1, 9.81 - 1e-4 * i, -0.3])


def scan_stamp(k):
    return T0_NS + 50 * 10**6 + k * 100 * 10**6


def points(k, lidar):
    """Expected points (x, y, z, intensity, t_s, ring) of scan k, in message order."""
    i = np.arange(N_PTS)
    x = (1.0 + 0.01 * i + k + lidar).astype(np.float32)
    y = (2.0 - 0.02 * i).astype(np.float32)
    z = (0.5 + 0.001 * i * k).astype(np.float32)
    inten = (i % 200).astype(np.float32)
    ring = (i % 32).astype(np.uint16)
    t = 1e-4 * i                                     # s since the first point
    return x, y, z, inten, t, ring


def ros_time(ns):
    import rospy
    return rospy.Time(ns // 10**9, ns % 10**9)


def write_imu(bag):
    from sensor_msgs.msg import Imu
    for i in range(N_IMU):
        m = Imu()
        m.header.seq = i
        m.header.stamp = ros_time(T0_NS + i * 2500000)
        w, a = imu_value(i)
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = w
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = a
        m.orientation_covariance[0] = -1
        bag.write('/alphasense/imu', m, m.header.stamp)


def write_hilti2022(path):
    import rosbag
    from sensor_msgs.msg import Image, PointCloud2, PointField
    bag = rosbag.Bag(path, 'w')
    write_imu(bag)
    F = PointField
    fields = [F('x', 0, F.FLOAT32, 1), F('y', 4, F.FLOAT32, 1), F('z', 8, F.FLOAT32, 1),
              F('intensity', 16, F.FLOAT32, 1), F('timestamp', 24, F.FLOAT64, 1),
              F('ring', 32, F.UINT16, 1)]
    dt = np.dtype({'names': ['x', 'y', 'z', 'intensity', 'timestamp', 'ring'],
                   'formats': ['<f4', '<f4', '<f4', '<f4', '<f8', '<u2'],
                   'offsets': [0, 4, 8, 16, 24, 32], 'itemsize': 48})
    for k in range(SCANS):
        x, y, z, inten, t, ring = points(k, 0)
        arr = np.zeros(N_PTS, dtype=dt)
        arr['x'], arr['y'], arr['z'], arr['intensity'], arr['ring'] = x, y, z, inten, ring
        s0 = scan_stamp(k)
        arr['timestamp'] = (s0 // 10**9 + (s0 % 10**9) * 1e-9) + t   # as a driver: ~1 ulp
        arr['x'][7] = np.nan                                   # not dense: dropped on import
        rows = arr.reshape(2, N_PTS // 2)
        m = PointCloud2()
        m.header.seq = k
        m.header.stamp = ros_time(scan_stamp(k))
        m.header.frame_id = 'pandar'
        m.height, m.width = 2, N_PTS // 2
        m.fields = fields
        m.is_bigendian = False
        m.point_step = 48
        m.row_step = 48 * (N_PTS // 2) + 16                    # 16 bytes of row padding
        m.is_dense = False
        m.data = b''.join(r.tobytes() + b'\xab' * 16 for r in rows)
        bag.write('/hesai/pandar', m, ros_time(scan_stamp(k) + 10**7))
    for j in range(2):
        m = Image()
        m.header.stamp = ros_time(T0_NS + 100 * 10**6 + j * 200 * 10**6)
        m.height, m.width, m.step, m.encoding = 3, 4, 4, 'mono8'
        m.data = bytes(range(j, j + 12))
        bag.write('/alphasense/cam0/image_raw', m, m.header.stamp)
    bag.close()


def write_hilti2021(path):
    import rosbag
    from genpy.dynamic import generate_dynamic
    from sensor_msgs.msg import PointCloud2, PointField
    livox = generate_dynamic('livox_ros_driver/CustomMsg', LIVOX_DEF)
    CustomMsg, CustomPoint = livox['livox_ros_driver/CustomMsg'], livox['livox_ros_driver/CustomPoint']
    if CustomMsg._md5sum != LIVOX_MD5:
        sys.exit('bag_python_bags: CustomMsg md5 %s, expected %s' % (CustomMsg._md5sum, LIVOX_MD5))
    bag = rosbag.Bag(path, 'w')
    write_imu(bag)
    F = PointField
    fields = [F('x', 0, F.FLOAT32, 1), F('y', 4, F.FLOAT32, 1), F('z', 8, F.FLOAT32, 1),
              F('intensity', 16, F.FLOAT32, 1), F('t', 20, F.UINT32, 1),
              F('reflectivity', 24, F.UINT16, 1), F('ring', 26, F.UINT8, 1),
              F('ambient', 28, F.UINT16, 1), F('range', 32, F.UINT32, 1)]
    dt = np.dtype({'names': ['x', 'y', 'z', 'intensity', 't', 'reflectivity', 'ring', 'ambient', 'range'],
                   'formats': ['>f4', '>f4', '>f4', '>f4', '>u4', '>u2', 'u1', '>u2', '>u4'],
                   'offsets': [0, 4, 8, 16, 20, 24, 26, 28, 32], 'itemsize': 48})
    for k in range(SCANS):
        x, y, z, inten, t, ring = points(k, 0)
        arr = np.zeros(N_PTS, dtype=dt)
        arr['x'], arr['y'], arr['z'], arr['intensity'], arr['ring'] = x, y, z, inten, ring
        arr['t'] = np.round(t * 1e9).astype(np.uint32)
        arr['reflectivity'], arr['ambient'], arr['range'] = 7, 9, 1234
        m = PointCloud2()
        m.header.seq = k
        m.header.stamp = ros_time(scan_stamp(k))
        m.header.frame_id = 'os_sensor'
        m.height, m.width = 1, N_PTS
        m.fields = fields
        m.is_bigendian = True
        m.point_step = 48
        m.row_step = 48 * N_PTS
        m.is_dense = True
        m.data = arr.tobytes()
        bag.write('/os_cloud_node/points', m, ros_time(scan_stamp(k) + 10**7))
        # Livox: points 0, 5, 10, ... at the origin (no return); timebase 1 us before point 1
        x, y, z, inten, t, ring = points(k, 1)
        lm = CustomMsg()
        lm.header.seq = k
        lm.header.stamp = ros_time(scan_stamp(k))
        lm.header.frame_id = 'livox_frame'
        lm.timebase = scan_stamp(k)
        lm.lidar_id = 1
        lm.rsvd = [0, 0, 0]
        for i in range(N_PTS):
            p = CustomPoint()
            p.offset_time = 1000 + int(round(t[i] * 1e9))
            if i % 5 == 0:
                p.x = p.y = p.z = 0.0
            else:
                p.x, p.y, p.z = float(x[i]), float(y[i]), float(z[i])
            p.reflectivity = int(inten[i])
            p.tag = 0x10
            p.line = int(ring[i] % 6)
            lm.points.append(p)
        lm.point_num = len(lm.points)
        bag.write('/livox/lidar', lm, ros_time(scan_stamp(k) + 10**7))
    bag.close()


# ---------------------------------------------------------------------------------------- check
def read_pcd(path):
    data = open(path, 'rb').read()
    hdr, pos = {}, 0
    while True:
        nl = data.index(b'\n', pos)
        line = data[pos:nl].decode().strip()
        pos = nl + 1
        if line.startswith('#') or not line:
            continue
        k, *v = line.split()
        hdr[k] = v
        if k == 'DATA':
            break
    assert hdr['DATA'][0] == 'binary', path
    types = {('F', '4'): '<f4', ('F', '8'): '<f8', ('U', '1'): 'u1', ('U', '2'): '<u2', ('U', '4'): '<u4'}
    dt = np.dtype([(n, types[(t, s)]) for n, s, t in zip(hdr['FIELDS'], hdr['SIZE'], hdr['TYPE'])])
    return np.frombuffer(data, dtype=dt, count=int(hdr['POINTS'][0]), offset=pos)


FAILURES = []


def expect(cond, what):
    if not cond:
        FAILURES.append(what)


def check_imu(seq):
    rows = [l.split(',') for l in open(seq + '/imu0/data.csv') if not l.startswith('#')]
    expect(len(rows) == N_IMU, '%s: %d IMU rows' % (seq, len(rows)))
    for i, r in enumerate(rows):
        w, a = imu_value(i)
        expect(int(r[0]) == T0_NS + i * 2500000, '%s: IMU %d stamp %s' % (seq, i, r[0]))
        expect([float(v) for v in r[1:7]] == w + a, '%s: IMU %d values %s' % (seq, i, r[1:7]))


def check_lidar(seq, lidar, first_offset_ns, keep, t_tol, exact_intensity, ring_mod):
    rows = [l.strip().split(',') for l in open('%s/%s/data.csv' % (seq, lidar)) if not l.startswith('#')]
    expect(len(rows) == SCANS, '%s/%s: %d scans' % (seq, lidar, len(rows)))
    for k, r in enumerate(rows):
        stamp = int(r[0])
        expect(stamp == scan_stamp(k) + first_offset_ns,
               '%s/%s scan %d: stamp %d, expected %d' % (seq, lidar, k, stamp, scan_stamp(k) + first_offset_ns))
        pc = read_pcd('%s/%s/data/%s' % (seq, lidar, r[1]))
        x, y, z, inten, t, ring = points(k, 1 if lidar == 'lidar1' else 0)
        idx = [i for i in range(N_PTS) if keep(i)]
        expect(len(pc) == len(idx), '%s/%s scan %d: %d points, expected %d' % (seq, lidar, k, len(pc), len(idx)))
        if len(pc) != len(idx):
            continue
        expect((pc['x'] == x[idx]).all() and (pc['y'] == y[idx]).all() and (pc['z'] == z[idx]).all(),
               '%s/%s scan %d: x y z differ' % (seq, lidar, k))
        expect((pc['ring'] == ring[idx] % ring_mod).all(), '%s/%s scan %d: ring differs' % (seq, lidar, k))
        if exact_intensity:
            expect((pc['intensity'] == inten[idx]).all(), '%s/%s scan %d: intensity differs' % (seq, lidar, k))
        t_exp = t[idx] - t[idx][0]
        err = np.abs(pc['t'].astype(np.float64) - t_exp).max()
        expect(err <= t_tol, '%s/%s scan %d: per-point time off by %g s' % (seq, lidar, k, err))


def check(d):
    h22, h21 = d + '/h22', d + '/h21'
    check_imu(h22)
    check_imu(h21)
    # Hesai absolute float64 seconds: resolution 2.4e-7 s at 1.6e9 s
    check_lidar(h22, 'lidar0', 0, lambda i: i != 7, 5e-7, True, 1 << 16)
    cams = [l for l in open(h22 + '/cam0/data.csv') if not l.startswith('#')]
    expect(len(cams) == 2, '%s: %d cam0 frames' % (h22, len(cams)))
    check_lidar(h21, 'lidar0', 0, lambda i: True, 2e-9, True, 1 << 16)
    # Livox: the earliest kept point (1) is at timebase + 1000 ns + 0.1 ms
    check_lidar(h21, 'lidar1', 1000 + 100000, lambda i: i % 5 != 0, 2e-9, True, 6)
    if FAILURES:
        print('\n'.join(FAILURES))
        sys.exit(1)
    print('bag_python_bags: all values as written')


def main():
    if len(sys.argv) != 3 or sys.argv[1] not in ('write', 'check'):
        sys.exit(__doc__)
    d = sys.argv[2]
    if sys.argv[1] == 'write':
        os.makedirs(d, exist_ok=True)
        write_hilti2022(d + '/hilti2022.bag')
        write_hilti2021(d + '/hilti2021.bag')
        print('bag_python_bags: wrote %s/hilti2022.bag and %s/hilti2021.bag' % (d, d))
    else:
        check(d)


if __name__ == '__main__':
    main()
