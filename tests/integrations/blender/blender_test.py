"""The Blender add-on tested inside real Blender (headless), on tracks of real speech.

Usage: blender_test.py GROUP   (GROUP: import, gltf or live; ctest runs each as one test)
Environment (ctest sets it): LIPSYNC (the built CLI), LIPSYNCD (the server), ADDON_ZIP (the zip
the build makes), SOURCE_DIR, WORK_DIR (a folder of the build tree for npm's cache).

What is real: flite speaks "Papa bought five more big maps." (its WAV and its own phone
timings), the built `lipsync` renders the tracks (JSON at 30 and 60 fps, Live Link Face CSV,
channel CSV, Rhubarb JSON, a track of a model with a renamed channel), Festival's recorded
timings of tests/data/closures/festival_1.lab are rendered too, lipsyncd runs on 127.0.0.1:0
for the live group, and the add-on is installed into Blender from its zip.

The import group also makes the demo face's .blend with the command docs/integrations.md gives
(clients/blender/demo_face.py) and, in a second Blender that opens it, imports a track on it.

The gltf group has Blender export the animated face as GLB, then reads the GLB back here with
an independent reader (struct over the JSON and BIN chunks), compares the morph-weight
animation with the track, and runs the Khronos glTF validator (npm gltf-validator, pinned by
gltf-validator/package-lock.json, installed with `npm ci` into the build tree; without npm or
the registry that one check is skipped with a message).

Exit 77 (ctest: skipped) only when Blender is not installed.
"""

import json
import os
import re
import shlex
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import wave

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "support"))
from listening_address import ServerProcess  # noqa: E402
SENTENCE = "Papa bought five more big maps."


def fail(message):
    print(f"FAIL: {message}", file=sys.stderr)
    sys.exit(1)


def run(command, timeout=120, **kwargs):
    result = subprocess.run(command, capture_output=True, text=True, timeout=timeout, **kwargs)
    if result.returncode != 0:
        fail(f"{' '.join(command)} exited {result.returncode}:\n{result.stdout}\n{result.stderr}")
    return result.stdout


def make_speech(work, lipsync, source_dir):
    """flite's speech and timings, and the tracks the built CLI renders from them."""
    files = {"wav": os.path.join(work, "papa.wav"), "psdur": os.path.join(work, "papa.psdur")}
    psdur = run(["flite", "-voice", "slt", "-psdur", "-t", SENTENCE, "-o", files["wav"]])
    with open(files["psdur"], "w", encoding="utf-8") as out:
        out.write(psdur)
    with wave.open(files["wav"], "rb") as stream:
        files["wav_seconds"] = stream.getnframes() / stream.getframerate()
    radio = ["--phone-set", "radio"]
    renders = {
        "track_json": (files["psdur"], ["--format", "json"]),
        "track_json60": (files["psdur"], ["--format", "json", "--fps", "60"]),
        "track_csv60": (files["psdur"], ["--format", "arkit-csv", "--fps", "60"]),
        "channels_csv": (files["psdur"], ["--format", "csv"]),
        "rhubarb_json": (files["psdur"], ["--format", "rhubarb-json"]),
        "festival_json": (os.path.join(source_dir, "tests/data/closures/festival_1.lab"), ["--format", "json"]),
    }
    for name, (source, options) in renders.items():
        extension = ".csv" if "csv" in name else ".json"
        files[name] = os.path.join(work, name + extension)
        run([lipsync, "render", source, *(radio if source.endswith("psdur") else []), *options,
             "-o", files[name]])
    # A model whose jaw channel has another name: a track "of another model".
    model = run([lipsync, "model", "dump"]).replace('"jaw_rotation"', '"jaw_angle"')
    model = re.sub(r'"name":\s*"default"', '"name": "renamed-jaw"', model, count=1)
    model_path = os.path.join(work, "renamed_jaw_model.json")
    with open(model_path, "w", encoding="utf-8") as out:
        out.write(model)
    files["other_model_json"] = os.path.join(work, "other_model.json")
    run([lipsync, "render", files["psdur"], *radio, "--model", model_path, "--format", "json",
         "-o", files["other_model_json"]])
    files["phonemes_json"] = os.path.join(work, "phonemes.json")
    phonemes, start = [], "0"
    for token in psdur.split():
        label, end = token.rsplit(":", 1)
        phonemes.append({"label": label, "start": float(start), "end": float(end)})
        start = end
    with open(files["phonemes_json"], "w", encoding="utf-8") as out:
        json.dump({"phone_set": "radio", "phonemes": phonemes}, out)
    return files


def unused_port():
    import socket
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def blender_environment(user_dir):
    # Debian's Blender embeds the system Python and takes its prefix from the `python3` first on
    # PATH: a pyenv or venv python3 there would hide Debian's numpy and grpc from it.
    search_path = os.pathsep.join([os.path.dirname(shutil.which("blender")), os.environ.get("PATH", "")])
    return dict(os.environ, PATH=search_path, BLENDER_USER_SCRIPTS=os.path.join(user_dir, "scripts"),
                BLENDER_USER_CONFIG=os.path.join(user_dir, "config"), PYTHONDONTWRITEBYTECODE="1")


def run_blender(config, work, user_dir, blend=None):
    """in_blender.py's checks of config's group, in a fresh Blender (on the .blend file `blend`)."""
    path = os.path.join(work, f"config_{config['group']}.json")
    with open(path, "w", encoding="utf-8") as out:
        json.dump(config, out)
    env = blender_environment(user_dir)
    command = ["blender", "-b", "--factory-startup", *([blend] if blend else []), "--python-exit-code", "1",
               "--python", os.path.join(HERE, "in_blender.py"), "--", path]
    started = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True, timeout=240, env=env)
    print(result.stderr[-20000:])
    print(f"blender ({config['group']}): exit {result.returncode} in {time.monotonic() - started:.1f} s")
    if result.returncode != 0:
        fail(f"the checks inside Blender failed; its stdout:\n{result.stdout[-8000:]}")


# ---- The GLB, read back without Blender ----------------------------------------------------------

COMPONENTS = {5126: ("f", 4)}
WIDTH = {"SCALAR": 1, "VEC3": 3}


def read_glb(path):
    with open(path, "rb") as stream:
        data = stream.read()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2 or length != len(data):
        fail(f"{path}: not a glTF 2 binary (magic {magic!r}, version {version}, length {length})")
    offset, document, binary = 12, None, b""
    while offset < length:
        chunk_length, chunk_type = struct.unpack_from("<II", data, offset)
        body = data[offset + 8:offset + 8 + chunk_length]
        if chunk_type == 0x4E4F534A:
            document = json.loads(body.decode("utf-8"))
        elif chunk_type == 0x004E4942:
            binary = body
        offset += 8 + chunk_length
    return document, binary


def accessor(document, binary, index):
    item = document["accessors"][index]
    if item["componentType"] not in COMPONENTS or item["type"] not in WIDTH:
        fail(f"accessor {index}: unexpected {item['componentType']} {item['type']}")
    view = document["bufferViews"][item["bufferView"]]
    code, size = COMPONENTS[item["componentType"]]
    width = WIDTH[item["type"]]
    stride = view.get("byteStride", size * width)
    start = view.get("byteOffset", 0) + item.get("byteOffset", 0)
    return [struct.unpack_from(f"<{width}{code}", binary, start + i * stride)
            for i in range(item["count"])]


def f32(value):
    return struct.unpack("<f", struct.pack("<f", value))[0]


def check_glb(glb, track, fps, start_frame=0):
    """The GLB's morph-weight animation is the track's, its times shifted by start_frame / fps:
    the exporter writes a key at frame f as f / fps seconds, counting from frame 0."""
    document, binary = read_glb(glb)
    meshes = [(n, node) for n, node in enumerate(document["nodes"]) if "mesh" in node]
    if len(meshes) != 1:
        fail(f"expected one mesh node, found {len(meshes)}")
    node_index, node = meshes[0]
    names = document["meshes"][node["mesh"]].get("extras", {}).get("targetNames", [])
    if sorted(names) != sorted(track["arkit_names"]):
        fail(f"the mesh's morph targets are not the 52 ARKit names: {names}")
    channels = [(a, c) for a in document.get("animations", []) for c in a["channels"]
                if c["target"].get("node") == node_index and c["target"]["path"] == "weights"]
    if len(channels) != 1:
        fail(f"expected one morph-weight channel on the face, found {len(channels)}")
    animation, channel = channels[0]
    sampler = animation["samplers"][channel["sampler"]]
    if sampler.get("interpolation", "LINEAR") != "LINEAR":
        fail(f"interpolation {sampler['interpolation']}, not LINEAR")
    times = [t[0] for t in accessor(document, binary, sampler["input"])]
    weights = [w[0] for w in accessor(document, binary, sampler["output"])]
    frames = track["frames"]
    if len(times) != len(frames) or len(weights) != len(frames) * len(names):
        fail(f"the GLB has {len(times)} times and {len(weights)} weights for a track of {len(frames)} "
             f"frames x {len(names)} targets (the exporter resampled the animation?)")
    index = {n: i for i, n in enumerate(track["arkit_names"])}
    worst_time = worst_weight = 0.0
    for i, frame in enumerate(frames):
        # Blender: frame = start_frame + t_us x fps / 1e6; the exporter writes frame / fps seconds.
        worst_time = max(worst_time, abs(times[i] - (start_frame / fps + frame["t_us"] / 1e6)))
        for k, name in enumerate(names):
            worst_weight = max(worst_weight, abs(weights[i * len(names) + k] - f32(frame["arkit"][index[name]])))
    closures = sum(1 for f in frames if f["kind"] in ("closure_start", "closure_end"))
    print(f"GLB keyed from frame {start_frame}: first key at {times[0] * 1e3:.3f} ms; {len(frames)} key times ({closures} closure key frames) x {len(names)} targets; "
          f"largest time error {worst_time * 1e6:.3f} µs, largest weight error {worst_weight:.2e}")
    if worst_time > 2e-6:
        fail(f"a key time differs from the track's by {worst_time * 1e6:.3f} µs")
    if worst_weight > 1e-6:
        fail(f"a morph weight differs from the track's by {worst_weight:.2e}")


def run_validator(glb, work):
    npm, node = shutil.which("npm"), shutil.which("node") or shutil.which("nodejs")
    if not npm or not node:
        print("SKIPPED the Khronos glTF validator check: npm/node not installed (apt-get install npm)")
        return
    folder = os.path.join(work, "gltf-validator")
    lock = os.path.join(HERE, "gltf-validator", "package-lock.json")
    installed = os.path.join(folder, "package-lock.json")
    module = os.path.join(folder, "node_modules", "gltf-validator")
    same_lock = os.path.isfile(installed) and open(installed).read() == open(lock).read()
    if not (os.path.isdir(module) and same_lock):
        os.makedirs(folder, exist_ok=True)
        for name in ("package.json", "package-lock.json", "validate.js"):
            shutil.copy(os.path.join(HERE, "gltf-validator", name), folder)
        result = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--cache", os.path.join(folder, ".npm")],
                                cwd=folder, capture_output=True, text=True, timeout=120)
        if result.returncode != 0:
            print("SKIPPED the Khronos glTF validator check: `npm ci` could not install gltf-validator "
                  f"(registry unreachable?): {result.stderr.strip()[-600:]}")
            return
    shutil.copy(os.path.join(HERE, "gltf-validator", "validate.js"), folder)
    report = json.loads(run([node, os.path.join(folder, "validate.js"), glb], timeout=60))
    issues = report["issues"]
    print(f"Khronos glTF validator {report['validatorVersion']}: {issues['numErrors']} errors, "
          f"{issues['numWarnings']} warnings, {issues['numInfos']} infos")
    if issues["numErrors"] or issues["numWarnings"]:
        fail("the validator found problems: " + json.dumps(issues["messages"][:10], indent=1))


def make_demo_face(source_dir, work):
    """The demo face's .blend, made by the command docs/integrations.md gives, as it gives it."""
    with open(os.path.join(source_dir, "docs/integrations.md"), encoding="utf-8") as stream:
        step = re.search(r"^(blender -b .*demo_face\.py -- )face\.blend\b", stream.read(), re.M)
    if step is None:
        fail("docs/integrations.md no longer shows the demo face's command (blender ... demo_face.py -- face.blend)")
    blend = os.path.join(work, "face.blend")
    # Blender finds a relative --python script from $PWD, which a child's cwd does not change.
    run(shlex.split(step.group(1)) + [blend], cwd=source_dir,
        env=dict(blender_environment(os.path.join(work, "blender-user")), PWD=source_dir))
    return blend


def main():
    if len(sys.argv) != 2 or sys.argv[1] not in ("import", "gltf", "live"):
        fail("usage: blender_test.py import|gltf|live")
    group = sys.argv[1]
    if shutil.which("blender") is None:
        print("SKIPPED: blender is not installed (apt-get install blender python3-numpy)")
        sys.exit(77)
    lipsync, lipsyncd = os.environ["LIPSYNC"], os.environ["LIPSYNCD"]
    source_dir, zip_path = os.environ["SOURCE_DIR"], os.environ["ADDON_ZIP"]
    if not os.path.isfile(zip_path):
        fail(f"the add-on's zip {zip_path} is missing: build the target lipsync_blender_addon")
    with tempfile.TemporaryDirectory(prefix=f"lipsync-blender-{group}-") as work:
        config = make_speech(work, lipsync, source_dir)
        formats = os.path.join(source_dir, "tests/data/formats")
        config["phoneme_files"] = {
            "flite": config["psdur"], "json": config["phonemes_json"],
            "textgrid": os.path.join(formats, "speech_long.TextGrid"),
            "textgrid_utf16": os.path.join(formats, "ipa_utf16be.TextGrid"),
            "timit": os.path.join(formats, "speech.PHN"), "lab": os.path.join(formats, "festival_mama.lab"),
            "pho": os.path.join(formats, "speech.pho")}
        config.update(group=group, work=work, addon_zip=zip_path, lipsync=lipsync, source_dir=source_dir,
                      face_json=os.path.join(source_dir, "data/face/viewer_face.json"),
                      glb=os.path.join(work, "face.glb"), glb_frame1=os.path.join(work, "face_frame1.glb"))
        server = None
        try:
            if group == "live":
                try:
                    server = ServerProcess([lipsyncd, "--listen", "127.0.0.1:0"])
                except RuntimeError as error:
                    fail(str(error))
                config.update(server=server.address, dead_server=f"127.0.0.1:{unused_port()}")
            run_blender(config, work, os.path.join(work, "blender-user"))
            if group == "import":
                config.update(group="demo", demo_blend=make_demo_face(source_dir, work))
                run_blender(config, work, os.path.join(work, "blender-user"), blend=config["demo_blend"])
        finally:
            if server:
                server.stop()
        if group == "gltf":
            with open(config["track_json"], encoding="utf-8") as stream:
                track = json.load(stream)
            check_glb(config["glb"], track, 24)
            # Blender's default start frame, 1: the whole animation one frame (1/24 s) late.
            check_glb(config["glb_frame1"], track, 24, start_frame=1)
            run_validator(config["glb"], os.environ.get("WORK_DIR", work))
    print(f"blender_test {group}: passed")


if __name__ == "__main__":
    main()
