#!/usr/bin/python3
"""Read a tacsim dataset in Python: numpy, and Pillow for the 8-bit PNGs (both come with Debian's
python3-matplotlib, which the README's commands install). No OpenEXR bindings needed: the float
images (normals, depth) are read by the small OpenEXR reader below, which takes the files tacsim
writes (single-part scan-line images of 32-bit float or 16-bit half channels, uncompressed, RLE-
or ZIP-compressed; tacsim wrote ZIP before 2026-11-30, RLE since); the 16-bit PNG normals
(normal_png), which Pillow would reduce to 8 bits, by the small PNG reader below.

    import sys; sys.path.insert(0, "tools")
    from pg_dataset import Dataset
    d = Dataset("out/default")
    d.info["sensor"]["camera"]["fx"], d.frames
    d.poses["obj_x"][7]            # poses.csv as a numpy structured array
    d.color(7)                     # (H, W, 3) uint8
    d.normal(7), d.depth(7)        # (H, W, 3) float32 unit normals in S; (H, W) float32 [m]
                                   # (normal: from normal_png where the dataset has only that)
    d.mask(7), d.points(7)         # (H, W) bool; (N, 3) float32, object frame [m]

From the shell, `python3 tools/pg_dataset.py DIR [FRAME]` describes a dataset and checks one
frame's files (a colour image that decodes whole, unit normals, depth, mask and points that
agree): exit 1 naming the file if not.
The format: README.md, "Dataset format".
"""
import csv
import json
import os
import struct
import sys
import zlib

try:
    import numpy as np
except ImportError:
    sys.exit(f"error: {sys.executable} has no numpy: run /usr/bin/python3 (Debian's "
             "python3-matplotlib brings numpy and Pillow), or install numpy for this one")

_EXR_MAGIC = 20000630
_EXR_TYPES = {1: np.dtype("<f2"), 2: np.dtype("<f4")}  # half, float (0, uint, is not written)
_EXR_LINES = {0: 1, 1: 1, 2: 1, 3: 16}  # lines per block: none, RLE, ZIPS, ZIP


def _exr_header(data, path):
    """The header's attributes (name -> (type, raw bytes)) and where the offset table starts."""
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != _EXR_MAGIC:
        raise ValueError(f"{path}: not an OpenEXR file")
    if version & 0x1A00:  # tiled, deep or multi-part
        raise ValueError(f"{path}: a tiled, deep or multi-part OpenEXR file; tacsim writes none")
    attrs, at = {}, 8
    while data[at] != 0:
        name_end = data.index(b"\0", at)
        type_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack_from("<i", data, type_end + 1)
        start = type_end + 5
        attrs[data[at:name_end].decode()] = (data[name_end + 1:type_end].decode(),
                                             data[start:start + size])
        at = start + size
    return attrs, at + 1


def _exr_channels(raw):
    """The channel list: [(name, numpy dtype)], in the file's (alphabetical) order."""
    channels, at = [], 0
    while raw[at] != 0:
        end = raw.index(b"\0", at)
        (pixel_type,) = struct.unpack_from("<i", raw, end + 1)
        channels.append((raw[at:end].decode(), pixel_type))
        at = end + 1 + 16  # type, pLinear + 3 reserved, x and y sampling
    return channels


def _unrle(packed):
    """OpenEXR's run-length code undone: a signed count byte n, then -n literal bytes (n < 0) or
    one byte repeated n + 1 times."""
    out, at = bytearray(), 0
    while at < len(packed):
        n = struct.unpack_from("<b", packed, at)[0]
        if n < 0:
            if at + 1 - n > len(packed):
                raise ValueError("an RLE run reaches past its block")
            out += packed[at + 1:at + 1 - n]
            at += 1 - n
        else:
            out += packed[at + 1:at + 2] * (n + 1)
            at += 2
    return bytes(out)


def _unpack_block(packed, size, compression):
    """A compressed block's bytes (ZIP: inflated; RLE: its runs expanded), then the predictor undone
    and the two halves interleaved back, as both codes store them."""
    expanded = zlib.decompress(packed) if compression in (2, 3) else _unrle(packed)
    t = np.frombuffer(expanded, dtype=np.uint8)
    if t.size != size:
        raise ValueError(f"a compressed block expands to {t.size} bytes, not {size}")
    t = np.cumsum(t.astype(np.int64) - 128, dtype=np.int64)  # t[i] = t[i-1] + d[i] - 128
    t = ((t + 128) & 0xFF).astype(np.uint8)
    out = np.empty(size, dtype=np.uint8)
    half = (size + 1) // 2
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def read_exr(path):
    """An OpenEXR image as float32 (H, W, C), channels in the file's order; tacsim's normals come
    as B, G, R (z, y, x) there and are returned here as R, G, B (x, y, z); depth as (H, W, 1).
    ValueError naming the file for one that is not such an image, damaged or cut short."""
    with open(path, "rb") as f:
        data = f.read()
    try:
        return _decode_exr(data, path)
    except (struct.error, zlib.error, IndexError, KeyError) as e:
        raise ValueError(f"{path}: damaged or cut short ({type(e).__name__}: {e})") from None


def _decode_exr(data, path):
    attrs, at = _exr_header(data, path)
    compression = attrs["compression"][1][0]
    if compression not in _EXR_LINES:
        raise ValueError(f"{path}: compression {compression} is not read here (none, RLE, ZIPS, "
                         "ZIP)")
    channels = _exr_channels(attrs["channels"][1])
    for name, pixel_type in channels:
        if pixel_type not in _EXR_TYPES:
            raise ValueError(f"{path}: channel {name} is of pixel type {pixel_type}")
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])
    width, height = x1 - x0 + 1, y1 - y0 + 1
    lines = _EXR_LINES[compression]
    blocks = (height + lines - 1) // lines
    offsets = struct.unpack_from(f"<{blocks}Q", data, at)
    row_bytes = sum(_EXR_TYPES[t].itemsize for _, t in channels) * width
    image = np.empty((height, len(channels), width), dtype=np.float32)
    for offset in offsets:
        y, packed_size = struct.unpack_from("<ii", data, offset)
        n = min(lines, y1 + 1 - y)
        packed = data[offset + 8:offset + 8 + packed_size]
        if len(packed) != packed_size:
            raise ValueError(f"{path}: damaged or cut short (the block of line {y} ends past the "
                             "file's end)")
        size = n * row_bytes
        try:
            block = packed if packed_size == size else _unpack_block(packed, size, compression)
        except ValueError as e:
            raise ValueError(f"{path}: damaged ({e}, the block of line {y})") from None
        at_byte = 0
        for row in range(y - y0, y - y0 + n):
            for c, (_, pixel_type) in enumerate(channels):
                dtype = _EXR_TYPES[pixel_type]
                image[row, c] = np.frombuffer(block, dtype=dtype, count=width, offset=at_byte)
                at_byte += dtype.itemsize * width
    image = image.transpose(0, 2, 1)
    names = [name for name, _ in channels]
    if names == ["B", "G", "R"]:
        image = image[:, :, ::-1]
    return np.ascontiguousarray(image)


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 4: 2, 6: 4}  # colour type -> channels (gray, RGB, gray+alpha, RGBA)


def read_png(path):
    """A PNG image as uint8 or uint16 (H, W, C) with its own bit depth: Pillow reduces 16-bit
    colour PNGs (tacsim's normal_png) to 8 bits. Takes 8- and 16-bit, non-interlaced gray or
    colour images without palette, as tacsim writes; ValueError naming the file otherwise."""
    with open(path, "rb") as f:
        data = f.read()
    try:
        return _decode_png(data, path)
    except (struct.error, zlib.error, IndexError) as e:
        raise ValueError(f"{path}: damaged or cut short ({type(e).__name__}: {e})") from None


def _decode_png(data, path):
    if not data.startswith(_PNG_SIGNATURE):
        raise ValueError(f"{path}: not a PNG file")
    at, header, packed = len(_PNG_SIGNATURE), None, []
    while True:
        size, kind = struct.unpack_from(">I4s", data, at)
        body = data[at + 8:at + 8 + size]
        (crc,) = struct.unpack_from(">I", data, at + 8 + size)
        if len(body) != size or zlib.crc32(kind + body) != crc:
            raise ValueError(f"{path}: damaged or cut short (chunk {kind.decode('latin-1')})")
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            packed.append(body)
        elif kind == b"IEND":
            break
        at += 12 + size
    if header is None:
        raise ValueError(f"{path}: a PNG without its header chunk (IHDR)")
    width, height, bits, colour, _, _, interlace = header
    if bits not in (8, 16) or colour not in _PNG_CHANNELS or interlace:
        raise ValueError(f"{path}: a PNG of bit depth {bits}, colour type {colour}, interlace "
                         f"{interlace}: tacsim writes 8 or 16 bits, no palette, not interlaced")
    step = _PNG_CHANNELS[colour] * bits // 8  # bytes per pixel, the filters' left neighbour
    row_bytes = width * step
    raw = zlib.decompress(b"".join(packed))
    if len(raw) != height * (row_bytes + 1):
        raise ValueError(f"{path}: the image data inflates to {len(raw)} bytes, not "
                         f"{height * (row_bytes + 1)}")
    rows = np.frombuffer(raw, dtype=np.uint8).reshape(height, row_bytes + 1)
    kinds = rows[:, 0]
    if kinds.max(initial=0) > 4:
        y = int(np.argmax(kinds > 4))
        raise ValueError(f"{path}: row {y} has filter type {kinds[y]}")
    if (kinds >= 3).any():  # Average or Paeth somewhere: each byte needs the one just decoded
        image = _unfilter_diagonals(kinds, rows[:, 1:], width, step)
    else:
        image = np.zeros((height + 1, row_bytes), dtype=np.uint8)  # row 0: zeros above the first
        for y in range(height):
            kind, line, above = kinds[y], rows[y, 1:], image[y]
            if kind == 0:
                image[y + 1] = line
            elif kind == 1:  # Sub: a running sum of each byte position in the pixel, modulo 256
                image[y + 1] = np.cumsum(line.reshape(width, step), axis=0, dtype=np.uint8).ravel()
            else:  # Up
                image[y + 1] = line + above
        image = image[1:]
    if bits == 16:
        image = image.view(">u2").astype(np.uint16)
    return image.reshape(height, width, _PNG_CHANNELS[colour])


def _unfilter_diagonals(kinds, lines, width, step):
    """Undoes any mix of the five filters: a pixel needs its left, upper and upper-left
    neighbours, all on the two anti-diagonals before its own, so each anti-diagonal is decoded
    at once (width + height steps, where a byte at a time took 0.35 s a 120x160 frame of 16-bit
    normals; tacsim writes every row with the Paeth filter since 2026-11-30)."""
    height = len(kinds)
    filtered = lines.reshape(height, width, step).astype(np.int16)
    image = np.zeros((height + 1, width + 1, step), dtype=np.int16)  # a row and column of zeros
    kind = kinds.astype(np.int16)[:, None]
    for d in range(width + height - 1):
        ys = np.arange(max(0, d - width + 1), min(height - 1, d) + 1)
        xs = d - ys
        left, up, upper_left = image[ys + 1, xs], image[ys, xs + 1], image[ys, xs]
        estimate = left + up - upper_left
        to_left, to_up = np.abs(estimate - left), np.abs(estimate - up)
        to_upper_left = np.abs(estimate - upper_left)
        paeth = np.where((to_left <= to_up) & (to_left <= to_upper_left), left,
                         np.where(to_up <= to_upper_left, up, upper_left))
        k = kind[ys]
        predictor = np.select([k == 0, k == 1, k == 2, k == 3],
                              [np.zeros_like(left), left, up, (left + up) >> 1], paeth)
        image[ys + 1, xs + 1] = (filtered[ys, xs] + predictor) & 0xFF
    return image[1:, 1:].astype(np.uint8).reshape(height, width * step)


def read_ply(path):
    """tacsim's binary PLY (float x y z, perhaps nx ny nz) as float32 (N, 3 or 6)."""
    with open(path, "rb") as f:
        data = f.read()
    at = data.find(b"end_header\n")
    header = data[:max(at, 0)].decode("latin-1").splitlines()
    if at < 0 or not header or header[0] != "ply" or "format binary_little_endian 1.0" not in header:
        raise ValueError(f"{path}: not a binary little-endian PLY file")
    end = at + len(b"end_header\n")
    try:
        count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    except (StopIteration, IndexError, ValueError):
        raise ValueError(f"{path}: no vertex count in the PLY header") from None
    fields = sum(1 for line in header if line.startswith("property float"))
    if len(data) - end < 4 * count * fields:
        raise ValueError(f"{path}: cut short: {count} points of {fields} floats need "
                         f"{4 * count * fields} bytes after the header, the file has {len(data) - end}")
    return np.frombuffer(data, dtype="<f4", count=count * fields, offset=end).reshape(count, fields)


def _read_8bit(path, mode):
    """An 8-bit PNG through Pillow (converted to `mode` unless None), its errors naming the file
    (Pillow's own name none: "image file is truncated")."""
    from PIL import Image
    try:
        with Image.open(path) as image:
            return np.asarray(image.convert(mode) if mode else image.copy())
    except OSError as e:
        if isinstance(e, FileNotFoundError):
            raise
        raise ValueError(f"{path}: damaged or cut short ({e})") from None


class Dataset:
    """A dataset folder: dataset.json as `info`, poses.csv as `poses`, and its frames."""

    def __init__(self, folder):
        self.dir = folder
        index = os.path.join(folder, "sensors.json")
        if not os.path.exists(os.path.join(folder, "dataset.json")) and os.path.exists(index):
            with open(index) as f:
                names = [str(name) for name in json.load(f).get("sensors", [])]
            raise ValueError(f"{folder}: not a dataset, but a render of several sensors, one "
                             f"dataset each: {', '.join(os.path.join(folder, n) for n in names)}")
        with open(os.path.join(folder, "dataset.json")) as f:
            self.info = json.load(f)
        self.frames = self.info["frames"]
        with open(os.path.join(folder, "poses.csv")) as f:
            rows = list(csv.reader(f))
        header = rows[0]
        types = [("frame", "i8")] + [(name, "f8") for name in header[1:]]
        # Empty cells (a recording's unknown poses and contacts) become NaN.
        values = [tuple([int(r[0])] + [float(v) if v else np.nan for v in r[1:]]) for r in rows[1:]]
        self.poses = np.array(values, dtype=types)

    def path(self, output, frame):
        if output not in self.info["outputs"]:
            raise ValueError(f"{self.dir}: has no {output} output (it has "
                             f"{', '.join(self.info['outputs'])})")
        extension = {"normal": ".exr", "depth": ".exr", "points": ".ply"}.get(output, ".png")
        return os.path.join(self.dir, output, f"{frame:06d}{extension}")

    def color(self, frame):
        return _read_8bit(self.path("color", frame), "RGB")

    def background(self):
        return _read_8bit(os.path.join(self.dir, "background.png"), "RGB")

    def normal(self, frame):
        if "normal" not in self.info["outputs"] and "normal_png" in self.info["outputs"]:
            return self.normal_png(frame)
        return read_exr(self.path("normal", frame))

    def normal_png(self, frame):
        """The normal_png output decoded as the C++ reader does: n = png / 65535 * 2 - 1, made
        unit length again (within 3e-5 of the float normals)."""
        png = read_png(self.path("normal_png", frame))
        if png.dtype != np.uint16 or png.shape[2] != 3:
            raise ValueError(f"{self.path('normal_png', frame)}: {png.dtype.itemsize * 8}-bit with "
                             f"{png.shape[2]} channels; normal_png is 16-bit RGB")
        n = png.astype(np.float32) / 65535 * 2 - 1
        length = np.linalg.norm(n, axis=2, keepdims=True)
        return np.where(length > 0, n / np.where(length > 0, length, 1), n).astype(np.float32)

    def depth(self, frame):
        return read_exr(self.path("depth", frame))[:, :, 0]

    def mask(self, frame):
        return _read_8bit(self.path("mask", frame), None) > 0

    def points(self, frame):
        return read_ply(self.path("points", frame))[:, :3]


def check(folder, frame):
    """Prints what the dataset holds and checks one frame's files against each other."""
    d = Dataset(folder)
    if not 0 <= frame < d.frames:
        raise ValueError(f"frame {frame}: {folder} has frames 0 to {d.frames - 1}")
    outputs = d.info["outputs"]
    width, height = d.info["width"], d.info["height"]
    print(f"dataset   {folder}: {d.frames} frames at {width}x{height}, outputs {', '.join(outputs)}")
    if "color" in outputs:
        c = d.color(frame)
        assert c.shape == (height, width, 3), f"{d.path('color', frame)}: shape {c.shape}"
        print(f"color     frame {frame}: mean level {c.mean():.1f}")
    if "normal" in outputs:
        n = d.normal(frame)
        length = np.linalg.norm(n, axis=2)
        assert n.shape == (height, width, 3), f"{d.path('normal', frame)}: shape {n.shape}"
        assert np.abs(length - 1).max() < 1e-5, f"{d.path('normal', frame)}: normals not unit"
        assert (n[:, :, 2] > 0).all(), f"{d.path('normal', frame)}: a normal faces the camera"
        print(f"normal    frame {frame}: unit, tilted up to {np.degrees(np.arccos(n[:, :, 2].min())):.2f} deg")
    if "normal_png" in outputs:
        n16 = d.normal_png(frame)
        assert n16.shape == (height, width, 3), f"{d.path('normal_png', frame)}: shape {n16.shape}"
        if "normal" in outputs:
            off = np.abs(n16 - n).max()
            assert off < 1e-4, f"{d.path('normal_png', frame)}: {off:.2e} off the normal output"
            print(f"normal_png frame {frame}: within {off:.1e} of normal")
        else:
            print(f"normal_png frame {frame}: tilted up to "
                  f"{np.degrees(np.arccos(min(1.0, n16[:, :, 2].min()))):.2f} deg")
    if "depth" in outputs:
        u = d.depth(frame)
        assert u.shape == (height, width) and (u >= 0).all(), f"{d.path('depth', frame)}"
        print(f"depth     frame {frame}: deepest {u.max() * 1e3:.6f} mm, {int((u > 0).sum())} px > 0")
    if "mask" in outputs:
        m = d.mask(frame)
        if "depth" in outputs:
            assert (u[m] > 0).all(), f"{d.path('mask', frame)}: contact where the depth is 0"
        print(f"mask      frame {frame}: {int(m.sum())} px")
        if "points" in outputs:
            p = d.points(frame)
            assert len(p) <= m.sum(), f"{d.path('points', frame)}: more points than mask pixels"
            print(f"points    frame {frame}: {len(p)}")
    row = d.poses[frame]
    print(f"pose      frame {frame}: object at ({row['obj_x']:.9f}, {row['obj_y']:.9f}, "
          f"{row['obj_z']:.9f}) m, contact {row['contact']:.0f}")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3) or sys.argv[1].startswith("-"):
        print(__doc__)
        sys.exit(2)
    try:
        check(sys.argv[1], int(sys.argv[2]) if len(sys.argv) == 3 else 0)
    except (OSError, ValueError, KeyError, AssertionError) as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(1)
