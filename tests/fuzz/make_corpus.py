#!/usr/bin/env python3
"""Writes the seed corpus of the fuzz targets into tests/fuzz/corpus/<target>/ (docs/fuzzing.md).

Each target gets a few valid inputs in the project's formats and a few broken ones (each broken
one is refused with an input error today). The files are checked in; rerun this after changing a
seed here (`python3 tests/fuzz/make_corpus.py`, needs protoc for the proto seeds). It only adds and
overwrites its own files: inputs saved from fuzzing runs can sit beside them.
"""

import math
import os
import struct
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
CORPUS = os.path.join(HERE, "corpus")


def put(target, name, data):
    d = os.path.join(CORPUS, target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


# --- OBJ: uploaded garment meshes ------------------------------------------------------------------

def grid_obj(nx, ny, h=0.05, uv_scale=1.0, seams=False, quads=False, normals=False, z=lambda x, y: 0.0):
    lines = ["# a %dx%d grid, %g m spacing" % (nx, ny, h), "o cloth"]
    for j in range(ny):
        for i in range(nx):
            x, y = i * h, j * h
            lines.append("v %.6g %.6g %.6g" % (x, y, z(x, y)))
    vid = lambda i, j: j * nx + i + 1
    if normals:
        lines.append("vn 0 0 1")
    if seams:
        faces = []
        vt = 0
        for j in range(ny - 1):
            for i in range(nx - 1):
                for tri in (((i, j), (i + 1, j), (i + 1, j + 1)), ((i, j), (i + 1, j + 1), (i, j + 1))):
                    ids = []
                    for (a, b) in tri:
                        lines.append("vt %.6g %.6g" % (a * h * uv_scale, b * h * uv_scale))
                        vt += 1
                        ids.append("%d/%d" % (vid(a, b), vt))
                    faces.append("f " + " ".join(ids))
        lines += faces
    else:
        for j in range(ny):
            for i in range(nx):
                lines.append("vt %.6g %.6g" % (i * h * uv_scale, j * h * uv_scale))
        for j in range(ny - 1):
            for i in range(nx - 1):
                c = [vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)]
                fmt = (lambda v: "%d/%d/1" % (v, v)) if normals else (lambda v: "%d/%d" % (v, v))
                if quads:
                    lines.append("f " + " ".join(fmt(v) for v in c))
                else:
                    lines.append("f %s %s %s" % (fmt(c[0]), fmt(c[1]), fmt(c[2])))
                    lines.append("f %s %s %s" % (fmt(c[0]), fmt(c[2]), fmt(c[3])))
    return "\n".join(lines) + "\n"


def obj_seeds():
    t = "fuzz_obj_import"
    put(t, "grid_uv_metres.obj", grid_obj(5, 4))
    put(t, "grid_uv_scaled.obj", grid_obj(4, 4, uv_scale=3.0))       # kRescale
    put(t, "grid_uv_seams.obj", grid_obj(3, 3, seams=True))          # per-corner uvs
    put(t, "grid_quads_normals.obj", grid_obj(4, 3, quads=True, normals=True,
                                              z=lambda x, y: 0.02 * math.sin(20 * x)))
    put(t, "no_uv_negative_index.obj",
        "mtllib cloth.mtl\ng panel\nusemtl fabric\nv 0 0 0\nv 0.1 0 0\nv 0.1 0.1 0\nf -3 -2 -1\n"
        "v 0 0.1 0\ns off\nf 1 3 4\n")
    put(t, "atlas_uv.obj",  # texture-atlas uvs: dropped
        "v 0 0 0\nv 0.2 0 0\nv 0.2 0.1 0\nv 0 0.1 0\nvt 0.9 0.1\nvt 0.1 0.5\nvt 0.3 0.3\nvt 0.7 0.9\n"
        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    # Broken: each refused with an InputError.
    put(t, "bad_index_out_of_range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    put(t, "bad_nan_vertex.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    put(t, "bad_unused_vertex.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 5 5 5\nf 1 2 3\n")
    put(t, "bad_degenerate.obj", "v 0 0 0\nv 0.1 0 0\nv 0.2 0 0\nf 1 2 3\n")
    put(t, "bad_non_manifold.obj",
        "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 -0.1 0\nv 0 0 0.1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n")
    put(t, "bad_millimetres.obj", "v 0 0 0\nv 1000 0 0\nv 0 1000 0\nf 1 2 3\n")
    put(t, "bad_short_v_line.obj", "v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    put(t, "bad_no_faces.obj", "v 0 0 0\nv 1 0 0\nl 1 2\n")


# --- our trajectory CSV / JSON ---------------------------------------------------------------------

CSV_HEADER = "time,arm,x,y,z,qw,qx,qy,qz,gripper"


def traj_rows():
    rows = []
    for k in range(5):
        t = 0.5 * k
        g = 0.035 if k < 2 else 0.0
        rows.append((t, "left", 0.1 + 0.02 * k, 0.15, 0.09 - 0.01 * k, 0, 1, 0, 0, g))
        rows.append((t, "right", 0.1 + 0.02 * k, -0.15, 0.09 - 0.01 * k, 0, 1, 0, 0, g))
    return rows


def csv_seeds():
    t = "fuzz_trajectory_csv"
    body = "\n".join(",".join(str(v) for v in r) for r in traj_rows())
    put(t, "docs_example.csv", CSV_HEADER + "\n0,left,0.1,0.15,0.09,0,1,0,0,0.035\n0,right,0.1,-0.15,0.09,0,1,0,0,0.035\n"
        "0.5,left,0.1,0.15,0.05,0,1,0,0,0.035\n0.5,right,0.1,-0.15,0.05,0,1,0,0,0.035\n")
    put(t, "fold_master_start.csv", "# written by gd\n# master_start_time = 1753696464.25\n" + CSV_HEADER + "\n" + body + "\n")
    put(t, "reordered_columns_crlf.csv",
        "arm, gripper, time, qw, qx, qy, qz, x, y, z\r\n\r\nleft, 0.035, 0, 0.7071067811865476, 0, 0, 0.7071067811865476, 0.1, 0.1, 0.2\r\n"
        "left, 0, 1e-1, 1, 0, 0, 0, 0.2, 0.1, 0.2\r\n")
    put(t, "one_arm.csv", CSV_HEADER + "\n0,right,0,0,0.1,1,0,0,0,0.02\n2.5,right,0.3,-0.2,0.1,0,0,0,1,0.01\n")
    put(t, "bad_quaternion.csv", CSV_HEADER + "\n0,left,0,0,0,1,1,0,0,0.035\n")
    put(t, "bad_time_order.csv", CSV_HEADER + "\n1,left,0,0,0,1,0,0,0,0.035\n0.5,left,0,0,0,1,0,0,0,0.035\n")
    put(t, "bad_unknown_column.csv", CSV_HEADER + ",extra\n0,left,0,0,0,1,0,0,0,0.035,1\n")
    put(t, "bad_arm_and_nan.csv", CSV_HEADER + "\n0,middle,0,0,0,1,0,0,0,0.035\n0,left,nan,0,0,1,0,0,0,inf\n")
    put(t, "bad_comment.csv", "# master_start_time 12\n" + CSV_HEADER + "\n")


def json_sample(t, x, y, z, q=(0, 1, 0, 0), g=0.035):
    return '{"t": %s, "position": [%s, %s, %s], "quat_wxyz": [%s, %s, %s, %s], "gripper": %s}' % (
        t, x, y, z, q[0], q[1], q[2], q[3], g)


def json_seeds():
    t = "fuzz_trajectory_json"
    put(t, "docs_example.json",
        '{\n "format": "gd-trajectory", "version": 1, "frame": "world", "master_start_time": 0,\n'
        ' "left":  [' + json_sample(0, 0.1, 0.15, 0.09) + '],\n'
        ' "right": [' + json_sample(0, 0.1, -0.15, 0.09) + ']\n}\n')
    left = ", ".join(json_sample(0.5 * k, 0.1 + 0.02 * k, 0.15, 0.09 - 0.01 * k, g=0.035 if k < 2 else 0)
                     for k in range(4))
    put(t, "fold.json", '{"master_start_time": 1753696464.25, "left": [' + left + '], "right": []}\n')
    put(t, "minimal_right.json", '{"right":[' + json_sample(1e-3, 0, 0, 0, (1, 0, 0, 0), 0) + "]}")
    put(t, "bad_version.json", '{"format": "gd-trajectory", "version": 2, "left": []}')
    put(t, "bad_unknown_field.json", '{"left": [], "speed": 3}')
    put(t, "bad_sample.json", '{"left": [{"t": 0, "position": [0, 0], "quat_wxyz": [1, 0, 0, 0], "gripper": 0}]}')
    put(t, "bad_types.json", '{"left": [{"t": "0", "position": [0, 0, null], "quat_wxyz": {}, "gripper": -1}],'
        ' "frame": "base", "master_start_time": 1e400}')
    put(t, "bad_not_object.json", '[1, 2, {"left": []}]')
    put(t, "bad_syntax.json", '{"left": [')


# --- RGBench joints CSV pair -------------------------------------------------------------------------

RGB_HEADER = "time,pos_1,pos_2,pos_3,pos_4,pos_5,pos_6,pos_gripper,pos_x,pos_y,pos_z,orn_w,orn_x,orn_y,orn_z"


def rgbench_seeds():
    t = "fuzz_rgbench_joints"
    left = (RGB_HEADER + "\n1753696464.5,0.1,0.2,0.3,0.4,0.5,0.6,0.035,0.10,0.00,0.20,0.7071067811865476,0,0,0.7071067811865476\n"
            "1753696465.5,0.1,0.2,0.3,0.4,0.5,0.6,0.0,0.20,0.05,0.30,1,0,0,0\n")
    right = (RGB_HEADER + "\n1753696464.25,0,0,0,0,0,0,0.01,0.30,0.00,0.10,0,1,0,0\n"
             "1753696465.25,0,0,0,0,0,0,0.02,0.30,0.10,0.10,0,1,0,0\n")
    put(t, "pair.csv", left + "---\n" + right)
    # Columns in another order, joint columns dropped, CRLF.
    put(t, "pair_reordered_crlf.csv",
        "orn_w,orn_x,orn_y,orn_z,pos_x,pos_y,pos_z,pos_gripper,time\r\n1,0,0,0,0.1,0,0.2,0.035,10\r\n"
        "1,0,0,0,0.1,0,0.25,0.03,10.5\r\n\n---\n" + right)
    put(t, "same_file_both_arms.csv", right)  # no separator: both files get it
    put(t, "bad_missing_orn_w.csv",
        "time,pos_1,pos_2,pos_3,pos_4,pos_5,pos_6,pos_gripper,pos_x,pos_y,pos_z,orn_x,orn_y,orn_z\n"
        "1753696464.5,0,0,0,0,0,0,0.035,0.1,0,0.2,0,0,0\n---\n" + right)
    put(t, "bad_short_row.csv", RGB_HEADER + "\n1753696464.5,0,0,0,0,0,0,0.035,0.1,0,0.2,1,0,0\n---\n" + right)
    put(t, "bad_time_order.csv", left + "1753696465.0,0,0,0,0,0,0,0.035,0.1,0,0.2,1,0,0,0\n---\n" + right)
    put(t, "bad_empty_right.csv", left + "---\n")


# --- point clouds: PCD and PLY -----------------------------------------------------------------------

def cloud_points(n=12):
    return [(0.05 * (i % 4), 0.04 * (i // 4), 0.01 * ((i * 7) % 5)) for i in range(n)]


def pcd_header(fields, sizes, types, n, data):
    return ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\n"
            "WIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n" % (
                " ".join(fields), " ".join(map(str, sizes)), " ".join(types), " ".join("1" for _ in fields),
                n, n, data)).encode()


def lzf_literals(raw):
    """LZF stream of literal runs only (a control byte < 32 copies the next ctrl+1 bytes)."""
    out = bytearray()
    for i in range(0, len(raw), 32):
        chunk = raw[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def cloud_seeds():
    t = "fuzz_cloud_io"
    pts = cloud_points()
    n = len(pts)
    # ascii, as Open3D writes it (x y z rgb, one NaN point)
    body = "".join(("nan nan nan 4.2108e+06\n" if i == 3 else "%g %g %g 4.2108e+06\n" % p) for i, p in enumerate(pts))
    put(t, "open3d_ascii.pcd", pcd_header("x y z rgb".split(), [4, 4, 4, 4], "FFFF", n, "ascii") + body.encode())
    # binary float32 x y z
    put(t, "binary_f32.pcd", pcd_header("xyz", [4, 4, 4], "FFF", n, "binary") +
        b"".join(struct.pack("<3f", *p) for p in pts))
    # binary float64 x y z + float rgb (Open3D's layout for double clouds)
    put(t, "binary_f64_rgb.pcd", pcd_header("x y z rgb".split(), [8, 8, 8, 4], "FFFF", n, "binary") +
        b"".join(struct.pack("<3df", p[0], p[1], p[2], 1.0) for p in pts))
    # binary_compressed: uint32 compressed size, uint32 raw size, LZF of the fields one after another
    raw = b"".join(struct.pack("<%df" % n, *[p[k] for p in pts]) for k in range(3))
    comp = lzf_literals(raw)
    put(t, "binary_compressed.pcd", pcd_header("xyz", [4, 4, 4], "FFF", n, "binary_compressed") +
        struct.pack("<II", len(comp), len(raw)) + comp)
    # broken
    put(t, "bad_truncated_binary.pcd", pcd_header("xyz", [4, 4, 4], "FFF", 100, "binary") + b"abc")
    put(t, "bad_no_xyz.pcd", pcd_header("abc", [4, 4, 4], "FFF", 1, "ascii") + b"1 2 3\n")
    put(t, "bad_int_fields.pcd", pcd_header("xyz", [1, 1, 1], "UUU", 2, "ascii") + b"1 2 3\n4 5 6\n")
    put(t, "bad_garbage.pcd", "this is not a point cloud\n")

    ply_head = lambda fmt, n, typ, extra="": ("ply\nformat %s 1.0\ncomment gd fuzz seed\nelement vertex %d\n"
                                              "property %s x\nproperty %s y\nproperty %s z\n%send_header\n" % (
                                                  fmt, n, typ, typ, typ, extra)).encode()
    put(t, "ascii.ply", ply_head("ascii", n, "float") + "".join("%g %g %g\n" % p for p in pts).encode())
    put(t, "ascii_mesh_colors.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
        "property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0 255 0 0\n1 0 0.5 0 255 0\n0 1 0.25 0 0 255\n3 0 1 2\n")
    put(t, "binary_le_float.ply", ply_head("binary_little_endian", n, "float") +
        b"".join(struct.pack("<3f", *p) for p in pts))
    put(t, "binary_be_double.ply", ply_head("binary_big_endian", 4, "double") +
        b"".join(struct.pack(">3d", *p) for p in pts[:4]))
    put(t, "bad_truncated.ply", ply_head("binary_little_endian", 1000, "float") + b"\x00" * 20)
    put(t, "bad_no_vertices.ply", "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n")
    # What the fuzzer found (docs/fuzzing.md), kept as regression inputs.
    put(t, "found_pcd_unknown_first_line.pcd",  # PCL: SEGV formatting the fields of a field-less header
        b"this is 7 - Point Cloud Data file format\n" + pcd_header("xyz", [4, 4, 4], "FFF", 2, "ascii").split(b"\n", 1)[1] +
        b"0 0 0\n1 1 1\n")
    put(t, "found_pcd_huge_size.pcd",  # PCL: allocates POINTS x 4 GiB before reading
        "FIELDS x y z\nSIZE 4294967295 1 1\nTYPE U U U\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
        "1 2 3\n4 5 6\n")
    put(t, "found_ply_green_blue_no_red.ply",  # PCL's PLYReader: failed assert (abort)
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "property uchar green\nproperty uchar blue\nend_header\n0 0 0 1 2\n1 0 0.5 3 4\n0 1 0.25 5 6\n")


# --- proto requests ----------------------------------------------------------------------------------

PROTO_TEXT = {
    # (first byte, message, text format)
    "create_generated": (0, "CreateScenesRequest",
                         'garment: "tshirt" material: "cotton" vertices: 400 mode: "pseudo" seed: 7 count: 4 '
                         'settings { dt: 0.005 self_contact: true jaw_radius: 0.02 } '
                         'randomization { yaw_deg: 10 offset_m: 0.02 } '
                         'garment_params { key: "length" value: 0.7 } garment_params { key: "sleeve_length" value: 0.2 }'),
    "create_mesh": (0, "CreateScenesRequest", 'mesh_id: "m-0123456789abcdef" mode: "fixed_point" settings { grab_time: 0.5 }'),
    "step_actions": (1, "StepScenesRequest",
                     'scene_ids: "s-1" scene_ids: "s-2" substeps: 10 include_velocities: true '
                     'actions { scene_id: "s-1" arms { arm: ARM_LEFT pose { position { x: 0.1 y: 0.15 z: 0.05 } '
                     'orientation { w: 0 x: 1 y: 0 z: 0 } } gripper: 0.0 } '
                     'arms { arm: ARM_RIGHT pose { position { x: 0.1 y: -0.15 z: 0.05 } } gripper: 0.035 } } '
                     'actions { scene_id: "s-2" release_targets: true targets { '
                     'indices { dtype: "int32" shape: 2 data: "\\001\\000\\000\\000\\007\\000\\000\\000" } '
                     'positions { dtype: "float32" shape: 2 shape: 3 '
                     'data: "\\315\\314\\314=\\000\\000\\000\\000\\315\\314L>\\315\\314\\314=\\315\\314L>\\315\\314L>" } } }'),
    "step_bad_arm": (1, "StepScenesRequest", 'actions { scene_id: "s-1" arms { arm: ARM_UNSPECIFIED } }'),
    "step_bad_shape": (1, "StepScenesRequest",
                       'actions { scene_id: "s-1" targets { indices { dtype: "int32" shape: 3 data: "\\001\\000\\000\\000" } } }'),
    "job_csv": (2, "SubmitJobRequest",
                'garment: "towel" material: "denim" task: "fold" vertices: 500 trajectory_format: "csv" '
                'trajectory: "time,arm,x,y,z,qw,qx,qy,qz,gripper\\n0,left,0.1,0.15,0.09,0,1,0,0,0.035\\n" '
                'dt: 0.01 time_scale: 1.5 settle: 0.5 self_contact: false icp: true label: "fuzz seed" '
                'task_params { key: "fold_duration" value: 6 } garment_params { key: "length" value: 0.5 }'),
    "job_capture": (2, "SubmitJobRequest", 'mesh_id: "m-1" task: "grasp" mode: "fixed_point" capture: "rgbench/towel_grasp_1"'),
    "array_vec3": (3, "Array",
                   'dtype: "float32" shape: 1 shape: 3 data: "\\000\\000\\200?\\000\\000\\000@\\000\\000@@"'),
    "array_indices": (3, "Array", 'dtype: "int32" shape: 3 data: "\\001\\000\\000\\000\\002\\000\\000\\000\\003\\000\\000\\000"'),
    "array_bad_shape": (3, "Array", 'dtype: "float32" shape: -1 shape: 3 data: "abc"'),
    "array_huge_rows": (3, "Array", 'dtype: "int32" shape: 4611686018427387904 data: ""'),
}


def proto_seeds():
    t = "fuzz_proto_convert"
    proto_dir = os.path.join(ROOT, "proto")
    for name, (kind, msg, text) in PROTO_TEXT.items():
        r = subprocess.run(["protoc", "--proto_path=" + proto_dir,
                            "--encode=garmentdynamics.v1." + msg, "garmentdynamics/v1/garmentdynamics.proto"],
                           input=text.encode(), capture_output=True, check=False)
        if r.returncode != 0:
            sys.exit("protoc --encode %s (%s): %s" % (msg, name, r.stderr.decode()))
        put(t, name + ".bin", bytes([kind]) + r.stdout)


def main():
    obj_seeds()
    csv_seeds()
    json_seeds()
    rgbench_seeds()
    cloud_seeds()
    proto_seeds()
    total = sum(os.path.getsize(os.path.join(dp, f)) for dp, _, fs in os.walk(CORPUS) for f in fs)
    print("corpus: %d bytes in %s" % (total, CORPUS))


if __name__ == "__main__":
    main()
