#!/usr/bin/python3
"""Feeds damaged inputs to tacsim and patchgraph and checks that each is either used or refused
with a clear error: never a crash, a hang, a sanitizer report, an error that names no file, or a
non-finite result. docs/stress.md, "Damaged inputs".

Seven kinds of input, each mutated from a good one by a seeded random generator:
  scene    a scene file (JSON values replaced, scaled, removed, duplicated; the text cut or
           garbled), rendered with tacsim render
  mesh     a mesh file (glTF binary: its JSON's fields and its data; OBJ, STL and PLY, text and
           binary: bytes replaced, the file cut), rendered in a scene
  dataset  a rendered dataset (dataset.json, poses.csv, a frame's image), tracked (a damaged
           dataset.json or colour frame with --normals shading in some cases; a quarter of
           those not of poses.csv given to fit-sensor instead)
  config   patchgraph track's --config and --normals MODEL files (as a checkpoint below),
           tracked
  circles  label-ball's --circles file, the circles.csv a run writes and a user corrects by
           hand (cells replaced, rows removed, the text cut or garbled), labelling six presses
  checkpoint  train-normals' OUT.ckpt (bytes replaced, the file cut or emptied; or a tensor's
           values or the pickled structure, the archive's checksums mended), resumed
  recording  what patchgraph recording reads of a real sensor's session, as a user gathers and
           writes it: the --poses file (cells replaced, rows removed, the text garbled), the
           --sensor-file (JSON values replaced or scaled), a frame or the --background image
           (removed, cut, bytes replaced, another image in its place), or a --video of the
           frames (FFV1 or H.264: bytes replaced, the file cut or emptied); the dataset it makes
           tracked with the default model, and a refusal must leave no dataset behind

Usage: fuzz_inputs.py --tacsim PATH --patchgraph PATH --work DIR [--cases N] [--seed S]
                      [--kinds scene,mesh,...] [--timeout SECONDS]
Exit 0 when every case passed; 1 with the failing cases (their inputs kept under DIR/failed).
"""
import argparse
import copy
import io
import json
import math
import os
import random
import shutil
import struct
import subprocess
import sys
import zipfile
import zlib

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# Values that a parser must refuse or survive wherever they land.
ODD_VALUES = [0, -1, 1, 3, 0.5, -0.5, 1e-9, 1e-30, 1e30, 1e308, -1e308, 5e-324, 2**31, 2**63,
              -2**63 - 1, "", "abc", "a" * 2000, None, True, False, [], {}, [0], [0, 0, 0, 0],
              [[[[1]]]]]
# Odd file paths for string fields.
ODD_PATHS = ["", "/nonexistent/x.glb", "/tmp", "/dev/null", "../x", "/proc/self/status"]
# Words in an error that come from a library or the language, not from the tools' own checks.
VAGUE = ["basic_string", "bad_alloc", "json.exception", "std::", "vector::", "stoi", "stod",
         "what()", "c10::", "terminate called", "Could not convert"]
# Cells of a circles file: statuses, and numbers a hand might type.
CIRCLE_VALUES = ["found", "given", "no_press", "skipped", "none", "1000", "-5", "1e-9", "60.5",
                 "0.0127", "1e3", "12,5"]


# ----------------------------------------------------------------------------- JSON mutation

def json_nodes(x, path=()):
    yield path, x
    if isinstance(x, dict):
        for k, v in x.items():
            yield from json_nodes(v, path + (k,))
    elif isinstance(x, list):
        for i, v in enumerate(x):
            yield from json_nodes(v, path + (i,))


def json_get(x, path):
    for p in path:
        x = x[p]
    return x


def mutate_json(doc, rng, extra_values=()):
    """1-3 edits at random nodes: a value replaced or scaled, a key removed or added, an array
    emptied or repeated, a node copied over another."""
    doc = copy.deepcopy(doc)
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        nodes = [n for n in json_nodes(doc) if n[0]]
        if not nodes:
            break
        path, value = rng.choice(nodes)
        parent, key = json_get(doc, path[:-1]), path[-1]
        r = rng.random()
        if r < 0.4:
            parent[key] = copy.deepcopy(rng.choice(ODD_VALUES + list(extra_values)))
        elif r < 0.6 and isinstance(value, (int, float)) and not isinstance(value, bool):
            parent[key] = value * rng.choice([0, -1, 1e-6, 1e-3, 1e3, 1e6, 1e12])
        elif r < 0.7:
            del parent[key]
        elif r < 0.77 and isinstance(value, list):
            parent[key] = value * rng.choice([0, 2, 30])
        elif r < 0.83 and isinstance(value, dict):
            value["unknown_key"] = 1
        elif r < 0.9 and isinstance(value, str):
            parent[key] = rng.choice(ODD_PATHS + [value + "x", value[:-1]])
        else:
            parent[key] = copy.deepcopy(json_get(doc, rng.choice(nodes)[0]))
    return doc


def mutate_bytes(data, rng, alphabet=None):
    """The file cut short, or 1-20 bytes replaced (from `alphabet` for text formats)."""
    if not data or rng.random() < 0.3:
        return data[: rng.randrange(len(data))] if data else data
    b = bytearray(data)
    for _ in range(rng.randint(1, 20 if alphabet is None else 6)):
        i = rng.randrange(len(b))
        b[i] = rng.choice(alphabet) if alphabet else rng.randrange(256)
    if alphabet and rng.random() < 0.3:
        i = rng.randrange(len(b))
        b[i:i] = rng.choice([b"-1", b"99999999999999999999", b"nan", b"inf", b"1e400", b"0"])
    return bytes(b)


TEXT_ALPHABET = b"0123456789-+.eE \n/#vfnaxyz{}[],:\"\x00\xff"


# ----------------------------------------------------------------------------- the good inputs

def small_box():
    """A 10 mm box as vertices and 0-based triangles."""
    v = [(x, y, z) for x in (-0.005, 0.005) for y in (-0.005, 0.005) for z in (-0.005, 0.005)]
    f = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),
         (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    return v, f


def box_files():
    """The box in each text and binary format: {name: (extension, bytes, is_text)}."""
    v, f = small_box()
    obj = "".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join(
        f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)
    stl = "solid box\n"
    for t in f:
        stl += " facet normal 0 0 0\n  outer loop\n"
        stl += "".join("   vertex %g %g %g\n" % v[i] for i in t)
        stl += "  endloop\n endfacet\n"
    stl += "endsolid box\n"
    stl_bin = b"\0" * 80 + struct.pack("<I", len(f))
    for t in f:
        stl_bin += struct.pack("<3f", 0, 0, 0)
        for i in t:
            stl_bin += struct.pack("<3f", *v[i])
        stl_bin += b"\0\0"
    header = ("ply\nformat {}\nelement vertex {}\nproperty float x\nproperty float y\n"
              "property float z\nelement face {}\nproperty list uchar int vertex_indices\n"
              "end_header\n")
    ply = header.format("ascii 1.0", len(v), len(f)) + "".join(
        f"{x} {y} {z}\n" for x, y, z in v) + "".join(f"3 {a} {b} {c}\n" for a, b, c in f)
    ply_bin = header.format("binary_little_endian 1.0", len(v), len(f)).encode()
    ply_bin += b"".join(struct.pack("<3f", *p) for p in v)
    ply_bin += b"".join(struct.pack("<B3i", 3, *t) for t in f)
    return {"obj": ("obj", obj.encode(), True), "stl_text": ("stl", stl.encode(), True),
            "stl_binary": ("stl", stl_bin, False), "ply_text": ("ply", ply.encode(), True),
            "ply_binary": ("ply", ply_bin, False)}


def split_glb(data):
    json_length = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[20:20 + json_length]), data[20 + json_length:]


def join_glb(doc, binary_chunk):
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + binary_chunk
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


GLB_VALUES = [2, 4, 5, 7, 5120, 5121, 5123, 5125, 5126, 2**31 - 1, 2**32, -2**31, "VEC3",
              "SCALAR", "MAT4", 83256, 166464, 249720, 249721, 12]


def mutate_glb(doc, binary_chunk, rng):
    doc = copy.deepcopy(doc)
    r = rng.random()
    if r < 0.6:
        doc = mutate_json(doc, rng, GLB_VALUES)
    elif r < 0.8:  # a field the good file leaves out
        part = rng.choice(["bufferViews", "accessors", "nodes"])
        fields = {"bufferViews": ["byteStride", "byteOffset"],
                  "accessors": ["byteOffset", "normalized", "sparse"],
                  "nodes": ["matrix", "scale", "rotation", "translation", "children"]}[part]
        item = rng.choice(doc[part])
        item[rng.choice(fields)] = copy.deepcopy(rng.choice(
            GLB_VALUES + [[0] * 16, [1e300] * 16, [0, 0, 0], [0, 0, 0, 0], [0], {"count": 3}]))
    else:
        binary_chunk = mutate_bytes(binary_chunk, rng)
    data = join_glb(doc, binary_chunk)
    return data[: rng.randrange(len(data))] if rng.random() < 0.1 else data


# ----------------------------------------------------------------------------- running

class Fuzzer:
    def __init__(self, args):
        self.args = args
        self.work = os.path.abspath(args.work)
        self.failed_dir = os.path.join(self.work, "failed")
        shutil.rmtree(self.work, ignore_errors=True)
        os.makedirs(self.failed_dir)
        self.failures = []
        self.counts = {}  # kind -> {"used": n, "refused": n}

    def run(self, command, timeout=None):
        """(exit code or 'timeout', stderr lines)."""
        env = dict(os.environ)
        # A sanitizer build reports through its own exit code; leaks are not this test's subject.
        env.setdefault("ASAN_OPTIONS", "detect_leaks=0")
        try:
            p = subprocess.run(command, capture_output=True, timeout=timeout or self.args.timeout,
                               env=env)
            return p.returncode, p.stderr.decode("utf-8", "replace").strip().splitlines()
        except subprocess.TimeoutExpired:
            return "timeout", []

    def judge(self, kind, case, rc, err, names, keep, result_check=None, refusal_check=None):
        """Records the case; `names` are the paths one of which an error must name; `keep` the
        files to copy under failed/ when the case fails; `result_check` says what is wrong with
        the outputs of a run that exited 0, `refusal_check` with what a refusal left (each None
        if nothing)."""
        text = "\n".join(err)
        last = err[-1] if err else ""
        problem = None
        if rc == "timeout":
            problem = f"no answer in {self.args.timeout} s"
        elif "Sanitizer" in text or "runtime error:" in text:
            problem = "sanitizer report: " + next(l for l in err if "Sanitizer" in l or
                                                  "runtime error:" in l)
        elif rc not in (0, 1, 2, 3):
            problem = f"exit code {rc}"
        elif rc != 0 and not last.startswith("error:"):
            problem = "an exit without an 'error:' line"
        elif rc != 0 and any(w in last for w in VAGUE):
            problem = "an error in a library's words"
        elif rc != 0 and not any(n in last for n in names):
            problem = "an error that names none of " + ", ".join(names)
        elif rc == 0 and result_check is not None:
            problem = result_check()
        elif rc != 0 and refusal_check is not None:
            problem = refusal_check()
        if self.args.verbose:
            print(f"{kind} {case}: exit {rc}: {last[:200]}")
        counts = self.counts.setdefault(kind, {"used": 0, "refused": 0})
        counts["used" if rc == 0 else "refused"] += 1
        if problem:
            target = os.path.join(self.failed_dir, f"{kind}_{case}")
            os.makedirs(target, exist_ok=True)
            for path in keep:
                if os.path.isdir(path):
                    shutil.copytree(path, os.path.join(target, os.path.basename(path)))
                elif os.path.exists(path):
                    shutil.copy(path, target)
            self.failures.append(f"{kind} case {case}: {problem} (inputs in {target}; last "
                                 f"line: {last[:300]!r})")

    @staticmethod
    def json_not_finite(path, name):
        """What is wrong with a JSON file a run wrote: it must exist and hold finite numbers."""
        if not os.path.exists(path):
            return f"exit 0 without {name}"
        with open(path) as f:
            doc = json.load(f, parse_constant=lambda c: float("nan"))
        for where, value in json_nodes(doc):
            if isinstance(value, float) and not math.isfinite(value):
                return f"{name}: {'.'.join(map(str, where))} is {value}"
        return None

    @staticmethod
    def non_finite(result_dir):
        problem = Fuzzer.json_not_finite(os.path.join(result_dir, "summary.json"), "summary.json")
        if problem:
            return problem
        with open(os.path.join(result_dir, "poses.csv")) as f:
            for number, line in enumerate(f, 1):
                if number > 1 and any(c.strip().lower() in ("nan", "inf", "-inf")
                                      for c in line.split(",")):
                    return f"poses.csv line {number} is not finite"
        return None

    @staticmethod
    def labels_not_finite(out):
        """What is wrong with label-ball's outputs: its circles.csv and poses.csv must hold only
        finite numbers."""
        for name in ("circles.csv", "poses.csv"):
            path = os.path.join(out, name)
            if not os.path.exists(path):
                return f"exit 0 without {name}"
            with open(path) as f:
                for number, line in enumerate(f, 1):
                    if any(c.strip().lower() in ("nan", "-nan", "inf", "-inf")
                           for c in line.split(",")):
                        return f"{name} line {number} is not finite"
        return None

    # --------------------------------------------------------------------------- the kinds

    def scene_seeds(self):
        seeds = []
        for name in ["default.json", "examples/two_digits_pinch.json",
                     "examples/held_in_hand.json", "examples/long_cube_rock.json",
                     "examples/sphere_press.json"]:
            path = os.path.join(REPO, "scenes", name)
            with open(path) as f:
                scene = json.load(f)
            for obj in scene.get("objects", []):
                if "mesh" in obj and not os.path.isabs(obj["mesh"]):
                    obj["mesh"] = os.path.normpath(os.path.join(os.path.dirname(path),
                                                                obj["mesh"]))
            seeds.append(scene)
        # The default scene with every sensor field written out, the elastic gel and shadows.
        with open(os.path.join(self.base_dataset(), "dataset.json")) as f:
            sensor = json.load(f)["sensor"]
        full = copy.deepcopy(seeds[0])
        sensor["gel"]["elastic"]["enabled"] = True
        full["sensors"][0]["sensor"] = sensor
        full["render"]["shadows"] = True
        return seeds + [full]

    def base_dataset(self):
        path = os.path.join(self.work, "base")
        if not os.path.exists(path):
            rc, err = self.run([self.args.tacsim, "render", os.path.join(REPO, "scenes",
                                "default.json"), "--out", path, "--frames", "12", "-q"],
                               timeout=300)
            if rc != 0:
                sys.exit("fuzz_inputs: could not render the base dataset: " + "\n".join(err))
        return path

    def fuzz_scene(self, case, rng, seeds):
        base = rng.choice(seeds)
        if rng.random() < 0.85:
            text = json.dumps(mutate_json(base, rng, ODD_PATHS))
        else:
            text = mutate_bytes(json.dumps(base, indent=1).encode(), rng, TEXT_ALPHABET)
            text = text.decode("latin-1")
        scene = os.path.join(self.work, f"scene_{case}.json")
        with open(scene, "w", encoding="latin-1") as f:
            f.write(text)
        out = os.path.join(self.work, "out")
        shutil.rmtree(out, ignore_errors=True)
        rc, err = self.run([self.args.tacsim, "render", scene, "--out", out, "--frames", "2",
                            "-q", "--threads", "1"])
        self.judge("scene", case, rc, err, [scene], [scene])
        os.remove(scene)

    def fuzz_mesh(self, case, rng, boxes, glb):
        kind = rng.choice(list(boxes) + ["glb"] * 3)
        if kind == "glb":
            ext, data, depth = "glb", mutate_glb(glb[0], glb[1], rng), 0.0095
        else:
            ext, good, is_text = boxes[kind]
            data = mutate_bytes(good, rng, TEXT_ALPHABET if is_text else None)
            depth = 0.0045  # the box's centre: 0.5 mm into the gel
        mesh = os.path.join(self.work, f"mesh_{case}.{ext}")
        with open(mesh, "wb") as f:
            f.write(data)
        scene = os.path.join(self.work, f"mesh_{case}.json")
        with open(scene, "w") as f:
            json.dump({"frames": 1, "sensors": [{"name": "digit", "sensor": {"preset": "digit"}}],
                       "objects": [{"name": "part", "mesh": mesh, "pose": {
                           "position": [0, 0, depth], "rpy": [0.02, 0.01, 0.3]}}],
                       "render": {"outputs": ["color", "normal", "depth", "mask"], "seed": 1}},
                      f)
        out = os.path.join(self.work, "out")
        shutil.rmtree(out, ignore_errors=True)
        rc, err = self.run([self.args.tacsim, "render", scene, "--out", out, "-q", "--threads",
                            "1"])
        self.judge("mesh", case, rc, err, [mesh], [mesh, scene])
        os.remove(mesh)
        os.remove(scene)

    def track(self, kind, case, dataset, extra, names, keep):
        out = os.path.join(self.work, "out")
        shutil.rmtree(out, ignore_errors=True)
        method = ["patchgraph", "patchgraph", "gtpatch", "imagetoimage", "constvel"][case % 5]
        rc, err = self.run([self.args.patchgraph, "track", dataset, "--method", method, "--out",
                            out, "-q"] + extra)
        self.judge(kind, case, rc, err, names, keep, result_check=lambda: self.non_finite(out))

    def fuzz_dataset(self, case, rng):
        base = self.base_dataset()
        dataset = os.path.join(self.work, f"dataset_{case}")
        shutil.copytree(base, dataset)
        extra = []
        what = rng.choice(["dataset.json", "poses.csv", "frame", "frame", "frame"])
        if what == "dataset.json":
            path = os.path.join(dataset, "dataset.json")
            with open(path) as f:
                doc = json.load(f)
            with open(path, "w") as f:
                json.dump(mutate_json(doc, rng), f)
            # The shading's inverse reads the sensor model (lights, exposure, image size) itself.
            if rng.random() < 0.5:
                extra = ["--normals", "shading"]
        elif what == "poses.csv":
            path = os.path.join(dataset, "poses.csv")
            with open(path) as f:
                text = f.read()
            with open(path, "w") as f:
                f.write(mutate_csv(text, rng))
        else:
            folder = rng.choice(["color", "normal", "normal"])
            name = rng.choice(sorted(os.listdir(os.path.join(dataset, folder))))
            mutate_image(os.path.join(dataset, folder, name), rng, base)
            if folder == "color":
                extra = ["--normals", rng.choice([os.path.join(REPO, "models", "normals_unet.pt"),
                                                  "shading"])]
        if what != "poses.csv" and rng.random() < 0.25:
            self.fit_sensor(case, dataset)
        else:
            self.track("dataset", case, dataset, extra, [dataset], [dataset])
        shutil.rmtree(dataset)

    def fit_sensor(self, case, dataset):
        """fit-sensor on a damaged dataset: the frames' colours and normals fitted, or refused."""
        out = os.path.join(self.work, "fitted.json")
        if os.path.exists(out):
            os.remove(out)
        rc, err = self.run([self.args.patchgraph, "fit-sensor", dataset, "--iterations", "10",
                            "--out", out, "-q"])
        self.judge("dataset", case, rc, err, [dataset], [dataset],
                   result_check=lambda: self.json_not_finite(out, "the sensor file"))

    def fuzz_config(self, case, rng, config):
        base = self.base_dataset()
        if rng.random() < 0.7:
            path = os.path.join(self.work, f"config_{case}.json")
            doc = mutate_json(config, rng) if rng.random() < 0.5 else rescale_json(config, rng)
            with open(path, "w") as f:
                json.dump({k: v for k, v in doc.items() if rng.random() < 0.7}, f)
            extra = ["--config", path]
        else:
            path = os.path.join(self.work, f"model_{case}.pt")
            with open(os.path.join(REPO, "models", rng.choice(["normals_unet.pt",
                                                                "normals_mlp.pt"])), "rb") as f:
                data = f.read()
            with open(path, "wb") as f:
                f.write(mutate_checkpoint(data, rng))
            extra = ["--normals", path]
        self.track("config", case, base, extra, [path], [path])
        os.remove(path)

    def base_circles(self):
        """A render of six ball presses (colour only, as a real sensor records them) and the
        circles.csv label-ball finds in it (its labelled dataset kept in WORK/balls_labelled)."""
        balls = os.path.join(self.work, "balls")
        if not os.path.exists(balls):
            labelled = os.path.join(self.work, "balls_labelled")
            for command in ([self.args.tacsim, "render", os.path.join(REPO, "scenes", "normals",
                             "ball_val.json"), "--outputs", "color", "--frames", "6", "--out",
                             balls, "-q"],
                            [self.args.patchgraph, "label-ball", balls, "--diameter", "0.0127",
                             "--out", labelled, "-q"]):
                rc, err = self.run(command, timeout=300)
                if rc != 0:
                    sys.exit("fuzz_inputs: could not make the ball presses: " + "\n".join(err))
            with open(os.path.join(labelled, "circles.csv")) as f:
                self.circles_text = f.read()
        return balls, self.circles_text

    def fuzz_circles(self, case, rng):
        balls, text = self.base_circles()
        path = os.path.join(self.work, f"circles_{case}.csv")
        if rng.random() < 0.85:
            damaged = mutate_csv(text, rng, CIRCLE_VALUES)
        else:
            damaged = mutate_bytes(text.encode(), rng, TEXT_ALPHABET).decode("latin-1")
        with open(path, "w", encoding="latin-1") as f:
            f.write(damaged)
        out = os.path.join(self.work, "out")
        shutil.rmtree(out, ignore_errors=True)
        rc, err = self.run([self.args.patchgraph, "label-ball", balls, "--diameter", "0.0127",
                            "--circles", path, "--out", out, "-q"])
        self.judge("circles", case, rc, err, [path], [path],
                   result_check=lambda: self.labels_not_finite(out))
        os.remove(path)

    def base_checkpoint(self):
        """The bytes of train-normals' checkpoint after one epoch of a small U-Net on the ball
        presses, and the labelled presses it trained on."""
        self.base_circles()
        labelled = os.path.join(self.work, "balls_labelled")
        model = os.path.join(self.work, "ckpt_base", "m.pt")
        if not hasattr(self, "checkpoint_bytes"):
            rc, err = self.run([self.args.patchgraph, "train-normals", "--data", labelled,
                                "--epochs", "1", "--depth", "3", "--width", "4", "--threads",
                                "1", "--out", model, "-q"], timeout=300)
            if rc != 0:
                sys.exit("fuzz_inputs: could not make the checkpoint: " + "\n".join(err))
            with open(model + ".ckpt", "rb") as f:
                self.checkpoint_bytes = f.read()
            shutil.rmtree(os.path.dirname(model))
        return labelled, self.checkpoint_bytes

    def fuzz_checkpoint(self, case, rng):
        labelled, good = self.base_checkpoint()
        folder = os.path.join(self.work, f"checkpoint_{case}")
        os.makedirs(folder)
        model = os.path.join(folder, "m.pt")
        damaged = mutate_checkpoint(good, rng)
        with open(model + ".ckpt", "wb") as f:
            f.write(damaged)

        def kept():  # a refused checkpoint stays as it was, for the user to look at
            if not os.path.exists(model + ".ckpt"):
                return "the refused checkpoint was removed"
            with open(model + ".ckpt", "rb") as f:
                return None if f.read() == damaged else "the refused checkpoint was changed"

        rc, err = self.run([self.args.patchgraph, "train-normals", "--data", labelled,
                            "--epochs", "2", "--depth", "3", "--width", "4", "--threads", "1",
                            "--resume", "--out", model, "-q"])
        self.judge("checkpoint", case, rc, err, [model + ".ckpt"], [folder], refusal_check=kept)
        shutil.rmtree(folder)

    def base_videos(self):
        """The base render's colour frames as videos, by file name: lossless (FFV1 in Matroska)
        and lossy (H.264 in MP4), made with the ffmpeg command; none without it."""
        if not hasattr(self, "videos"):
            self.videos = {}
            if shutil.which("ffmpeg") is None:
                return self.videos
            pattern = os.path.join(self.base_dataset(), "color", "%06d.png")
            for name, codec in (("frames.mkv", ["-c:v", "ffv1", "-pix_fmt", "bgr0"]),
                                ("frames.mp4", ["-c:v", "libx264", "-pix_fmt", "yuv420p"])):
                path = os.path.join(self.work, name)
                rc, _ = self.run(["ffmpeg", "-nostdin", "-loglevel", "error", "-y", "-framerate",
                                  "60", "-i", pattern] + codec + [path], timeout=120)
                if rc == 0:
                    with open(path, "rb") as f:
                        self.videos[name] = f.read()
        return self.videos

    def fuzz_recording(self, case, rng):
        """A session of the base render's colour frames, its no-contact image, its poses and its
        sensor, as `recording` takes a real sensor's, with one of them damaged; what recording
        accepts is tracked with the default model, and must track to finite poses or be refused
        naming the recording or the damaged file."""
        base = self.base_dataset()
        folder = os.path.join(self.work, f"recording_{case}")
        frames = os.path.join(folder, "frames")
        shutil.copytree(os.path.join(base, "color"), frames)
        background = os.path.join(folder, "background.png")
        shutil.copy(os.path.join(base, "background.png"), background)
        poses = os.path.join(folder, "poses.csv")
        with open(os.path.join(base, "poses.csv")) as f:
            lines = f.read().splitlines()
        if rng.random() < 0.5:  # the object's pose known at the start only, as a recording's
            header = lines[0].split(",")
            blank = [i for i, name in enumerate(header) if name.startswith("obj_") or
                     name == "contact"]
            for i in range(2, len(lines)):
                cells = lines[i].split(",")
                for j in blank:
                    cells[j] = ""
                lines[i] = ",".join(cells)
        with open(poses, "w") as f:
            f.write("\n".join(lines) + "\n")
        sensor = os.path.join(folder, "sensor.json")
        with open(os.path.join(base, "dataset.json")) as f:
            sensor_doc = json.load(f)["sensor"]
        what = rng.choice(["poses", "poses", "sensor", "sensor", "frame", "frame", "background",
                           "video", "video"])
        if what == "video" and not self.base_videos():
            what = "frame"  # no ffmpeg command to make the videos with
        if what == "poses":
            damaged = poses
            with open(poses) as f:
                text = f.read()
            if rng.random() < 0.85:
                text = mutate_csv(text, rng)
            else:
                text = mutate_bytes(text.encode(), rng, TEXT_ALPHABET).decode("latin-1")
            with open(poses, "w", encoding="latin-1") as f:
                f.write(text)
        elif what == "sensor":
            damaged = sensor
            sensor_doc = (mutate_json(sensor_doc, rng) if rng.random() < 0.6 else
                          rescale_json(sensor_doc, rng))
        elif what == "frame":
            damaged = os.path.join(frames, rng.choice(sorted(os.listdir(frames))))
            mutate_image(damaged, rng, base)
        elif what == "video":
            name, good = rng.choice(sorted(self.base_videos().items()))
            damaged = os.path.join(folder, name)
            with open(damaged, "wb") as f:
                f.write(mutate_bytes(good, rng) if rng.random() < 0.95 else b"")
        else:
            damaged = background
            mutate_image(background, rng, base)
        with open(sensor, "w") as f:
            json.dump(sensor_doc, f)
        rec = os.path.join(folder, "rec")
        motion = (["--poses", poses] if what == "poses" or rng.random() < 0.5 else
                  ["--static-sensor"])
        source = ["--video", damaged] if what == "video" else ["--images", frames]
        rc, err = self.run([self.args.patchgraph, "recording"] + source + [
                            "--background", background, "--sensor-file", sensor, "--out", rec,
                            "-q"] + motion)
        names = [damaged, frames] if what == "frame" else [damaged]
        if rc != 0:  # and nothing half made in its place
            self.judge("recording", case, rc, err, names, [folder], refusal_check=lambda: (
                "the refused recording left " + rec if os.path.exists(rec) else None))
        else:
            out = os.path.join(self.work, "out")
            shutil.rmtree(out, ignore_errors=True)
            rc, err = self.run([self.args.patchgraph, "track", rec, "--normals",
                                os.path.join(REPO, "models", "normals_unet.pt"), "--out", out,
                                "-q"])
            self.judge("recording", case, rc, err, [rec] + names, [folder],
                       result_check=lambda: self.non_finite(out))
        shutil.rmtree(folder)


def zip_entry_replaced(data, name, new):
    """The zip file `data` with the stored (uncompressed) entry `name` replaced by `new`, of the
    same length, and its CRC-32 mended in the local header and the central directory: damage
    the archive's checksums do not show, for the reader behind them to meet."""
    info = zipfile.ZipFile(io.BytesIO(data)).getinfo(name)
    assert info.compress_type == zipfile.ZIP_STORED and len(new) == info.file_size
    b = bytearray(data)
    local = info.header_offset
    name_len, extra_len = struct.unpack_from("<HH", b, local + 26)
    start = local + 30 + name_len + extra_len
    b[start:start + len(new)] = new
    crc = zlib.crc32(new) & 0xFFFFFFFF
    struct.pack_into("<I", b, local + 14, crc)
    central = b.find(b"PK\x01\x02", start + len(new))
    while central >= 0:
        entry_name_len = struct.unpack_from("<H", b, central + 28)[0]
        if bytes(b[central + 46:central + 46 + entry_name_len]) == name.encode():
            struct.pack_into("<I", b, central + 16, crc)
            break
        central = b.find(b"PK\x01\x02", central + 46)
    return bytes(b)


def mutate_checkpoint(data, rng):
    """A checkpoint's or a model file's bytes damaged: anywhere (the archive's checksums refuse it), or one
    tensor's values or the pickled structure with the checksums mended."""
    r = rng.random()
    if r < 0.3:
        return mutate_bytes(data, rng) if rng.random() < 0.9 else b""
    names = zipfile.ZipFile(io.BytesIO(data)).namelist()
    if r < 0.8:
        name = rng.choice([n for n in names if "/data/" in n])
        old = zipfile.ZipFile(io.BytesIO(data)).read(name)
        values = [struct.pack("<f", v) for v in (float("nan"), float("inf"), -float("inf"),
                                                 1e30, -1e30, 0.0)]
        new = bytearray(old)
        for _ in range(rng.randint(1, max(1, len(old) // 4))):
            i = 4 * rng.randrange(max(1, len(old) // 4))
            new[i:i + 4] = rng.choice(values)[: len(old) - i]
        r = rng.random()
        if r < 0.4:  # small finite values instead: weights a reader must take as they are
            new = b"".join(struct.pack("<f", rng.uniform(0.01, 0.1)) for _ in range(len(old) // 4))
            new += old[len(new):]
        elif r < 0.9:
            new = bytes(new)
        else:
            new = bytes(rng.randrange(256) for _ in old)
    else:
        name = next(n for n in names if n.endswith("data.pkl"))
        old = zipfile.ZipFile(io.BytesIO(data)).read(name)
        new = bytearray(old)
        for _ in range(rng.randint(1, 6)):
            new[rng.randrange(len(new))] = rng.randrange(256)
        new = bytes(new)
    return zip_entry_replaced(data, name, new)

def rescale_json(doc, rng):
    """Numbers scaled and booleans flipped: mostly valid settings, at their ranges' ends."""
    doc = copy.deepcopy(doc)
    for path, value in list(json_nodes(doc)):
        if not path or rng.random() > 0.3:
            continue
        parent, key = json_get(doc, path[:-1]), path[-1]
        if isinstance(value, bool):
            parent[key] = not value
        elif isinstance(value, int):
            parent[key] = int(value * rng.choice([0, 0.5, 2, 10, 1000]))
        elif isinstance(value, float):
            parent[key] = value * rng.choice([0, 0.01, 0.1, 0.5, 2, 10, 100])
    return doc


def mutate_csv(text, rng, extra_values=()):
    lines = text.splitlines()
    r = rng.random()
    if r < 0.15:
        lines = lines[: rng.randrange(len(lines))]
    elif r < 0.25:
        del lines[rng.randrange(1, len(lines))]
    else:
        for _ in range(rng.randint(1, 3)):
            i = rng.randrange(len(lines))
            cells = lines[i].split(",")
            cells[rng.randrange(len(cells))] = rng.choice(
                ["nan", "inf", "-inf", "", "1e308", "0", "-1", "x", "1,2", "\"3\"", "0.5",
                 "99999999999"] + list(extra_values))
            lines[i] = ",".join(cells)
    return "\n".join(lines) + "\n"


def mutate_image(path, rng, base):
    r = rng.random()
    if r < 0.15:
        os.remove(path)
        return
    if r < 0.3:  # another output's file, or a real image of another size, in its place
        source = rng.choice([os.path.join(base, "color", "000000.png"),
                             os.path.join(base, "normal", "000000.exr"),
                             os.path.join(base, "background.png"),
                             os.path.join(REPO, "..", "shared", "data", "digit",
                                          "bg_digit_240_320.jpg")])
        if os.path.exists(source):
            shutil.copy(source, path)
            return
    with open(path, "rb") as f:
        data = f.read()
    with open(path, "wb") as f:
        f.write(mutate_bytes(data, rng) if r < 0.95 else b"")


TRACK_CONFIG = {
    "depth": {"min_normal_dot_ray": 0.2, "disturbed_angle_rad": 0.005, "crop": True,
              "crop_margin_px": 4, "dst_backend": "real_fft", "integration": "parity"},
    "mask": {"min_depth_m": 1e-4, "relative_depth": 0, "core_relative_depth": 0.2},
    "icp": {"max_iterations": 30, "max_correspondence_m": 1e-3, "kernel": "huber",
            "kernel_scale_m": 1e-4, "symmetric": True, "max_normal_angle_rad": 0.25,
            "convergence_translation_m": 1e-7,
            "convergence_rotation_rad": 1e-6, "min_points": 20, "voxel_size_m": 0,
            "coarse_points": 128, "coarse_step_m": 2e-6, "min_eigenvalue_ratio": 5e-3,
            "flat_radius_m": 0, "min_residual_sigma_m": 1e-5}}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tacsim", required=True)
    parser.add_argument("--patchgraph", required=True)
    parser.add_argument("--work", required=True, help="scratch folder (emptied first)")
    parser.add_argument("--cases", type=int, default=40, help="cases per kind (default 40)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--kinds",
                        default="scene,mesh,dataset,config,circles,checkpoint,recording")
    parser.add_argument("--timeout", type=float, default=60, help="seconds per run")
    parser.add_argument("--verbose", action="store_true", help="one line per case")
    args = parser.parse_args()
    kinds = args.kinds.split(",")
    unknown = set(kinds) - {"scene", "mesh", "dataset", "config", "circles", "checkpoint",
                            "recording"}
    if unknown:
        parser.error("unknown kinds: " + ", ".join(sorted(unknown)))

    fuzzer = Fuzzer(args)
    seeds = fuzzer.scene_seeds() if "scene" in kinds else None
    boxes = box_files()
    with open(os.path.join(REPO, "meshes", "cube.glb"), "rb") as f:
        glb = split_glb(f.read())
    for case in range(args.cases):
        for kind in kinds:
            rng = random.Random(f"{args.seed}:{kind}:{case}")
            if kind == "scene":
                fuzzer.fuzz_scene(case, rng, seeds)
            elif kind == "mesh":
                fuzzer.fuzz_mesh(case, rng, boxes, glb)
            elif kind == "dataset":
                fuzzer.fuzz_dataset(case, rng)
            elif kind == "circles":
                fuzzer.fuzz_circles(case, rng)
            elif kind == "checkpoint":
                fuzzer.fuzz_checkpoint(case, rng)
            elif kind == "recording":
                fuzzer.fuzz_recording(case, rng)
            else:
                fuzzer.fuzz_config(case, rng, TRACK_CONFIG)
        done = case + 1
        if done % 10 == 0 or done == args.cases:
            print(f"{done}/{args.cases} cases per kind, {len(fuzzer.failures)} failing",
                  flush=True)

    for kind in kinds:
        c = fuzzer.counts.get(kind, {"used": 0, "refused": 0})
        print(f"{kind}: {c['used']} used, {c['refused']} refused")
        # Mutations that no longer reach the readers (every case refused at the same gate, or
        # none) would make this test pass on nothing: both outcomes must occur.
        if args.cases >= 20 and (c["used"] == 0 or c["refused"] < args.cases // 4):
            fuzzer.failures.append(f"{kind}: {c['used']} used and {c['refused']} refused of "
                                   f"{args.cases}: the mutations no longer exercise the reader")
    for failure in fuzzer.failures:
        print("FAIL", failure)
    return 1 if fuzzer.failures else 0


if __name__ == "__main__":
    sys.exit(main())
