#!/usr/bin/python3
"""Writes the generated seed inputs of tests/fuzz/corpus/ (the other seeds are
copies of test fixtures and heads of ../shared/data files, see
tests/fuzz/README.md).

  tests/fuzz/make_seeds.py [CORPUS_DIR]      (default: tests/fuzz/corpus beside this script)

Every seed is a valid input of its target, a few KB at most: a PCD of each DATA
kind, COLMAP model files (bin and txt) of one camera, two images and two points,
a COLMAP 3.8 database (SQLite, 512-byte pages), a ROS1 bag written with
python3-rosbag, a Livox CustomMsg with its definition, PointCloud2 layouts in
the point_cloud2 target's input encoding, g2o graphs, CSV and YAML files.
"""
import io
import os
import re
import sqlite3
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def put(corpus, target, name, data):
    folder = os.path.join(corpus, target)
    os.makedirs(folder, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(folder, name), 'wb') as f:
        f.write(data)


POINTS = [(1.0, 2.0, 0.5, 10.0, 0.0, 3), (1.5, -2.0, 0.25, 20.0, 0.01, 4),
          (-3.0, 0.5, 1.0, 30.0, 0.02, 5)]


def pcd_header(data, fields=('x', 'y', 'z', 'intensity', 't', 'ring'), size=(4, 4, 4, 4, 4, 2),
               type_=('F', 'F', 'F', 'F', 'F', 'U')):
    n = len(POINTS)
    return ('# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n'
            f'FIELDS {" ".join(fields)}\nSIZE {" ".join(map(str, size))}\n'
            f'TYPE {" ".join(type_)}\nCOUNT {" ".join("1" * len(fields))}\n'
            f'WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n')


def lzf_literal(raw):
    """LZF stream of literal runs only (what PCL's decompressor accepts)."""
    out = bytearray()
    for i in range(0, len(raw), 32):
        chunk = raw[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def pcd_seeds(corpus):
    ascii_rows = ''.join(f'{x} {y} {z} {i} {t} {r}\n' for x, y, z, i, t, r in POINTS)
    put(corpus, 'pcd', 'ascii.pcd', pcd_header('ascii') + ascii_rows)
    binary = b''.join(struct.pack('<5fH', *p) for p in POINTS)
    put(corpus, 'pcd', 'binary.pcd', pcd_header('binary').encode() + binary)
    # binary_compressed: fields stored one after the other (SoA), then LZF.
    soa = b''.join(struct.pack('<' + ('H' if k == 5 else 'f') * len(POINTS),
                               *[p[k] for p in POINTS]) for k in range(6))
    comp = lzf_literal(soa)
    put(corpus, 'pcd', 'binary_compressed.pcd',
        pcd_header('binary_compressed').encode() + struct.pack('<II', len(comp), len(soa)) + comp)
    put(corpus, 'pcd', 'xyz_only.pcd',
        pcd_header('ascii', ('x', 'y', 'z'), (4, 4, 4), ('F', 'F', 'F')) +
        ''.join(f'{x} {y} {z}\n' for x, y, z, *_ in POINTS))


def ply_seeds(corpus):
    head = ('ply\nformat {} 1.0\nelement vertex 3\nproperty float x\nproperty float y\n'
            'property float z\nproperty float intensity\nend_header\n')
    put(corpus, 'ply', 'ascii.ply',
        head.format('ascii') + ''.join(f'{x} {y} {z} {i}\n' for x, y, z, i, *_ in POINTS))
    put(corpus, 'ply', 'binary_le.ply', head.format('binary_little_endian').encode() +
        b''.join(struct.pack('<4f', *p[:4]) for p in POINTS))
    put(corpus, 'ply', 'binary_be.ply', head.format('binary_big_endian').encode() +
        b''.join(struct.pack('>4f', *p[:4]) for p in POINTS))


# COLMAP model: camera 1 (PINHOLE), images 1 and 2 with two points each, points 1 and 2.
CAM = (1, 1, 640, 480, (500.0, 500.0, 320.0, 240.0))
IMAGES = [(1, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1, 'cam0/data/100.png',
           [(10.5, 20.5, 1), (30.0, 40.0, 2)]),
          (2, (0.9998, 0.02, 0.0, 0.0), (-0.5, 0.0, 0.0), 1, 'cam0/data/200.png',
           [(12.5, 21.5, 1), (300.0, 400.0, 0xFFFFFFFFFFFFFFFF)])]
POINTS3D = [(1, (0.1, 0.2, 5.0), (255, 128, 0), 0.5, [(1, 0), (2, 0)]),
            (2, (1.0, -0.5, 7.0), (0, 0, 255), 1.25, [(1, 1)])]


def colmap_seeds(corpus):
    cid, model, w, h, params = CAM
    put(corpus, 'colmap_cameras_bin', 'cameras.bin',
        struct.pack('<QIiQQ4d', 1, cid, model, w, h, *params))
    put(corpus, 'colmap_cameras_txt', 'cameras.txt',
        '# Camera list with one line of data per camera:\n'
        '#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: 1\n'
        '1 PINHOLE 640 480 500 500 320 240\n2 SIMPLE_RADIAL 640 480 500 320 240 0.01\n')
    b = struct.pack('<Q', len(IMAGES))
    t = '# Image list with two lines of data per image:\n# Number of images: 2\n'
    for iid, q, tv, c, name, pts in IMAGES:
        b += struct.pack('<I4d3dI', iid, *q, *tv, c) + name.encode() + b'\0'
        b += struct.pack('<Q', len(pts)) + b''.join(struct.pack('<ddQ', *p) for p in pts)
        t += f'{iid} {" ".join(map(str, q))} {" ".join(map(str, tv))} {c} {name}\n'
        t += ' '.join(f'{x} {y} {-1 if p == 0xFFFFFFFFFFFFFFFF else p}' for x, y, p in pts) + '\n'
    put(corpus, 'colmap_images_bin', 'images.bin', b)
    put(corpus, 'colmap_images_txt', 'images.txt', t)
    b = struct.pack('<Q', len(POINTS3D))
    t = '# 3D point list with one line of data per point:\n# Number of points: 2\n'
    for pid, xyz, rgb, err, track in POINTS3D:
        b += struct.pack('<Q3d3Bd', pid, *xyz, *rgb, err) + struct.pack('<Q', len(track))
        b += b''.join(struct.pack('<II', *e) for e in track)
        t += (f'{pid} {" ".join(map(str, xyz))} {" ".join(map(str, rgb))} {err} ' +
              ' '.join(f'{i} {j}' for i, j in track) + '\n')
    put(corpus, 'colmap_points3d_bin', 'points3D.bin', b)
    put(corpus, 'colmap_points3d_txt', 'points3D.txt', t)
    # rigs.bin (COLMAP 3.12): u64 rigs; rig id u32, u32 sensors, ref sensor (type i32, id u32),
    # then per non-reference sensor: type i32, id u32, has_pose u8, [qvec 4d, tvec 3d].
    rigs = struct.pack('<QII', 1, 1, 2) + struct.pack('<iI', 0, 1)
    rigs += struct.pack('<iIB4d3d', 0, 2, 1, 1.0, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0)
    put(corpus, 'colmap_rigs_bin', 'rigs.bin', rigs)
    # frames.bin (COLMAP 3.12): u64 frames; frame id u32, rig id u32, qvec 4d, tvec 3d,
    # u32 data ids, each: sensor type i32, sensor id u32, data id u64.
    frames = struct.pack('<QII4d3dI', 1, 1, 1, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2)
    frames += struct.pack('<iIQ', 0, 1, 1) + struct.pack('<iIQ', 0, 2, 2)
    put(corpus, 'colmap_frames_bin', 'frames.bin', frames)


def database_seed(corpus):
    src = open(os.path.join(ROOT, 'colmap_ext/io/database.cc')).read()
    block = src[src.index('kCreateTables[] = {'):src.index('struct RequiredTable')]
    block = re.sub(r'//[^\n]*', '', block[block.index('{') + 1:])
    statements, current = [], ''
    for literal, comma in re.findall(r'"((?:[^"\\]|\\.)*)"|(,)', block):
        if comma:
            statements.append(current)
            current = ''
        else:
            current += literal
    path = os.path.join(corpus, 'colmap_database', 'database.db')
    os.makedirs(os.path.dirname(path), exist_ok=True)
    if os.path.exists(path):
        os.remove(path)
    db = sqlite3.connect(path)
    db.execute('PRAGMA page_size = 512')
    for statement in statements:
        db.execute(statement)
    db.execute('PRAGMA user_version = 3800')
    db.execute('INSERT INTO cameras VALUES (1, 1, 640, 480, ?, 0)',
               (struct.pack('<4d', 500, 500, 320, 240),))
    for iid, q, tv, c, name, pts in IMAGES:
        db.execute('INSERT INTO images VALUES (?, ?, 1, ?, ?, ?, ?, ?, ?, ?)',
                   (iid, name, *q, *tv))
        kp = b''.join(struct.pack('<6f', x, y, 1, 0, 0, 1) for x, y, _ in pts)
        db.execute('INSERT INTO keypoints VALUES (?, 2, 6, ?)', (iid, kp))
        db.execute('INSERT INTO descriptors VALUES (?, 2, 128, ?)', (iid, bytes(256)))
    pair_id = 1 * 2147483647 + 2
    m = struct.pack('<4I', 0, 0, 1, 1)
    db.execute('INSERT INTO matches VALUES (?, 2, 2, ?)', (pair_id, m))
    eye = struct.pack('<9d', 1, 0, 0, 0, 1, 0, 0, 0, 1)
    db.execute('INSERT INTO two_view_geometries VALUES (?, 2, 2, ?, 2, ?, ?, ?, ?, ?)',
               (pair_id, m, eye, eye, eye, struct.pack('<4d', 1, 0, 0, 0),
                struct.pack('<3d', 1, 0, 0)))
    db.execute('INSERT INTO pose_priors VALUES (1, ?, 1, ?)',
               (struct.pack('<3d', 0.1, 0.2, 0.3), struct.pack('<9d', 1, 0, 0, 0, 1, 0, 0, 0, 1)))
    db.commit()
    db.execute('VACUUM')
    db.close()


def bag_seed(corpus):
    try:
        import rosbag
        import rospy
        from sensor_msgs.msg import Image, Imu, PointCloud2, PointField
    except ImportError:
        print('make_seeds: python3-rosbag missing, bag seed skipped', file=sys.stderr)
        return
    t0 = 1646300000 * 10**9

    def stamp(ns):
        return rospy.Time(ns // 10**9, ns % 10**9)

    path = os.path.join(corpus, 'bag', 'velodyne.bag')
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with rosbag.Bag(path, 'w') as bag:
        for i in range(4):
            m = Imu()
            m.header.stamp = stamp(t0 + i * 25 * 10**6)
            m.angular_velocity.x = 0.01 * i
            m.linear_acceleration.z = 9.81
            bag.write('/imu/data', m, m.header.stamp)
        F = PointField
        for k in range(2):
            m = PointCloud2()
            m.header.stamp = stamp(t0 + 10**7 + k * 5 * 10**7)
            m.height, m.width = 1, 3
            m.fields = [F('x', 0, F.FLOAT32, 1), F('y', 4, F.FLOAT32, 1),
                        F('z', 8, F.FLOAT32, 1), F('intensity', 12, F.FLOAT32, 1),
                        F('time', 16, F.FLOAT32, 1), F('ring', 20, F.UINT16, 1)]
            m.point_step, m.row_step, m.is_dense = 24, 72, True
            m.data = b''.join(struct.pack('<5fHxx', *p) for p in POINTS)
            bag.write('/velodyne_points', m, m.header.stamp)
        m = Image()
        m.header.stamp = stamp(t0 + 2 * 10**7)
        m.height, m.width, m.step, m.encoding = 2, 3, 3, 'mono8'
        m.data = bytes(range(6))
        bag.write('/cam0/image_raw', m, m.header.stamp)


def livox_seed(corpus):
    src = open(os.path.join(ROOT, 'importers/bag_message.cc')).read()
    block = src[src.index('kLivoxCustomMsgDefinition[] ='):]
    block = block[:block.index(';')]
    text = ''.join(re.findall(r'"((?:[^"\\]|\\.)*)"', block)).encode().decode('unicode_escape')
    pts = [(0, 1.0, 2.0, 0.5, 10, 0, 3), (1000, 0.0, 0.0, 0.0, 0, 0, 1),
           (2000, -1.0, 0.5, 2.0, 200, 0, 5)]
    msg = struct.pack('<III', 7, 1646300000, 5) + struct.pack('<I', 5) + b'livox'
    msg += struct.pack('<QIB3B', 1646300000 * 10**9, len(pts), 0, 0, 0, 0)
    msg += struct.pack('<I', len(pts)) + b''.join(struct.pack('<I3f3B', *p) for p in pts)
    put(corpus, 'livox_msg', 'custom_msg.bin', text.encode() + b'\0' + msg)


def point_cloud2_seeds(corpus):
    # Input encoding of tests/fuzz/point_cloud2_fuzzer.cc; names: x y z intensity ring t
    # timestamp time = 0..7.
    def encode(points, fields, step, big=False, reference=0, unit=0, height=1):
        width = len(points) // height
        head = struct.pack('<IIIIBBBB', height, width, step, step * width, int(big), reference,
                           unit, len(fields))
        head += b''.join(struct.pack('<BIBI', n, o, d, 1) for n, o, d in fields)
        return head + b''.join(points)

    e = '>' if False else '<'
    velodyne = [struct.pack('<5fH2x', *p) for p in POINTS]
    put(corpus, 'point_cloud2', 'velodyne.bin',
        encode(velodyne, [(0, 0, 7), (1, 4, 7), (2, 8, 7), (3, 12, 7), (7, 16, 7), (4, 20, 4)],
               24, reference=4))
    hesai = [struct.pack('<4f4xdH6x', *p[:4], 1646300000.0 + p[4], p[5]) for p in POINTS]
    put(corpus, 'point_cloud2', 'hesai.bin',
        encode(hesai, [(0, 0, 7), (1, 4, 7), (2, 8, 7), (3, 12, 7), (6, 20, 8), (4, 28, 4)],
               36, reference=1 | 2))
    ouster = [struct.pack('>3f4xfIB3x', *p[:4], int(p[4] * 1e9), p[5]) for p in POINTS]
    put(corpus, 'point_cloud2', 'ouster_be.bin',
        encode(ouster, [(0, 0, 7), (1, 4, 7), (2, 8, 7), (3, 16, 7), (5, 20, 6), (4, 24, 2)],
               28, big=True, unit=1))
    del e


def text_seeds(corpus):
    put(corpus, 'tum', 'trajectory.txt',
        '# timestamp tx ty tz qx qy qz qw\n'
        '1646304541.627162 -3.45 6.27 1.79 0.6602272584 0.7510275859 0.003393373643 -0.006783616141\n'
        '1646304541.72719 -3.449054053 6.272641139 1.789474365 0.6602268845 0.751028485 0.003328722516 -0.006752423123\n'
        '1646304541.82721 -3.448218112 6.274981797 1.789025224 0.6602069707 0.751045526 0.003572958182 -0.006678901208\n')
    put(corpus, 'euroc_csv', 'groundtruth.csv',
        '#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], '
        'q_RS_z []\n'
        '1403636580838555648,4.688319,-1.786938,0.783338,0.534108,-0.153029,-0.827383,-0.082152\n'
        '1403636580843555328,4.688177,-1.786770,0.787350,0.534640,-0.152990,-0.826976,-0.082863\n')
    put(corpus, 'control_points', 'control_points.txt',
        '# timestamp_s id x y z \n1646304543.1571593 -3.45665 6.33555 1.9089 0 0 0 1\n'
        '1646304563.7530038 -12.55935 9.1834 1.9109 0 0 0 1\n')
    put(corpus, 'control_points', 'xyz.txt', '10.5 1 2 3\n11.5 4 5 6\n')
    cov = ' '.join(['1e-4', '0', '0', '0', '0', '0', '1e-4', '0', '0', '0', '0', '1e-4', '0',
                    '0', '0', '1e-3', '0', '0', '1e-3', '0', '1e-3'])
    put(corpus, 'lidar_constraints', 'lisfm.txt',
        '# t_i_ns t_j_ns tx ty tz qx qy qz qw cov(21)\n'
        f'1000000000 2000000000 0.5 0 0 0 0 0.0998334166 0.9950041653 {cov}\n'
        f'2000000000 3000000000 0.5 0.1 0 0 0 0 1 {cov}\n')
    full = ' '.join('1e-4' if r == c else '0' for r in range(6) for c in range(6))
    counts = ' '.join(['0'] * 25)
    put(corpus, 'lidar_constraints', 'gtsfm.txt',
        f'0 1 1 0 0 0.5 0 1 0 0 0 0 1 0 {full}\n'
        f'1.0e+00 2.0e+00 1 0 0 0.5 0 1 0 0.1 0 0 1 0 {full} {counts}\n')
    put(corpus, 'g2o', 'se2.g2o',
        'VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0.1\nVERTEX_SE2 2 2 0.1 0.2\n'
        'EDGE_SE2 0 1 1 0 0.1 100 0 0 100 0 1000\nEDGE_SE2 1 2 1 0.1 0.1 100 0 0 100 0 1000\n'
        'EDGE_SE2 0 2 2 0.1 0.2 50 0 0 50 0 500\n')
    info = ' '.join('100' if r == c else '0' for r in range(6) for c in range(r, 6))
    put(corpus, 'g2o', 'se3.g2o',
        'VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n'
        'VERTEX_SE3:QUAT 2 1 1 0 0 0 0.7071067812 0.7071067812\n'
        f'EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 {info}\n'
        f'EDGE_SE3:QUAT 1 2 0 1 0 0 0 0.7071067812 0.7071067812 {info}\n'
        'FIX 0\n')
    put(corpus, 'keyframe_covariances', 'keyframe_covariances.txt',
        '# t_ns cov(21)\n'
        f'1000000000 {cov}\n2000000000 {cov}\n')
    put(corpus, 'sequence_csv', 'imu.csv',
        '#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],'
        'a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n'
        '1000000000,0.01,-0.02,0.5,0.1,9.81,-0.3\n1002500000,0.02,-0.02,0.5,0.1,9.81,-0.3\n')
    put(corpus, 'sequence_csv', 'index.csv', '#timestamp [ns],filename\n0,0.pcd\n1,1.png\n')
    put(corpus, 'options_yaml', 'flat.yaml',
        'Section.flag: true\nIcp.max_iterations: 20\nstart_ns: 5\nseed: 42\n'
        'Lidar.min_range: 0.3\nLidar.max_range: 50\nratio: -1\noutput_path: out\n'
        'Icp.method: bayesian\nmode: exact\ninput_path: in\n')
    put(corpus, 'options_yaml', 'nested.yaml',
        '# sections as maps, an alias\nIcp:\n  iterations: 5\n  method: point_to_plane\n'
        'Lidar: {min_range: 1, max_range: 2}\ninput_path: "x y"\nquiet: 1\n')


def copy_seeds(corpus):
    copies = {
        'rig_yaml': [os.path.join(ROOT, 'tests/data/rig/example_rig.yaml')],
        'ply': [os.path.join(ROOT, 'tests/data/clouds/pcl_xyzi_ascii.ply'),
                os.path.join(ROOT, 'tests/data/clouds/pcl_xyzi_binary.ply')],
        'pcd': [os.path.join(ROOT, 'tests/data/clouds/pcl_xyzi_compressed.pcd')],
    }
    calib = os.path.join(ROOT, '..', 'shared', 'data', 'hilti_exp4_small', 'calibration')
    for name in ('calib_3_cam0-1-camchain-imucam.yaml', 'lidar_calibration.yaml'):
        if os.path.exists(os.path.join(calib, name)):
            copies.setdefault('kalibr', []).append(os.path.join(calib, name))
    for target, files in copies.items():
        for f in files:
            put(corpus, target, os.path.basename(f), open(f, 'rb').read())


def main():
    corpus = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, 'corpus')
    pcd_seeds(corpus)
    ply_seeds(corpus)
    colmap_seeds(corpus)
    database_seed(corpus)
    bag_seed(corpus)
    livox_seed(corpus)
    point_cloud2_seeds(corpus)
    text_seeds(corpus)
    copy_seeds(corpus)


if __name__ == '__main__':
    main()
