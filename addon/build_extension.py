"""Package VolPath for Blender and install it into a Blender executable. Never imports bpy.

    python addon/build_extension.py build                       -> dist/volpath-<version>.zip
    python addon/build_extension.py validate [ZIP_OR_DIR]       -> Blender's own validator
    python addon/build_extension.py install --blender /path/to/blender

build: the wheels named in blender_manifest.toml are produced into wheels/ (volpath_native built
from native/, the others downloaded for the exact version and platform the manifest names);
volpath_native's numba kernels are compiled for the portable CPU target from the wheel's own
sources and shipped inside the wheel (build_kernel_cache: the first render after an install then
loads them in seconds instead of compiling for minutes), the
add-on, the manifest and the wheels are staged in build/extension/, and Blender's extension tool
(blender_ext.py, shipped in the bpy wheel) builds the zip.

install: Blender >= 4.2 installs the zip as an extension into its user_default repository and
enables it. Older Blender (e.g. Debian's 3.4) gets a legacy add-on: addon/ copied as `volpath` into
its user scripts/addons, the wheels installed into scripts/addons/modules, enabled and saved in the
user preferences. Blender's BLENDER_USER_CONFIG / BLENDER_USER_SCRIPTS environment is honoured.
"""
from __future__ import annotations

import argparse
import base64
import hashlib
import importlib.util
import os
import pickle
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MANIFEST = ROOT / "blender_manifest.toml"
ADDON_DIR = ROOT / "addon"
WHEEL_DIR = ROOT / "wheels"
STAGE_DIR = ROOT / "build" / "extension"
DIST_DIR = ROOT / "dist"
LEGACY_MODULE = "volpath"  # the legacy add-on's package name
EXTENSION_MIN_VERSION = (4, 2)
KERNEL_BUILD_DIR = ROOT / "build" / "kernels"
# numba's codegen.magic_tuple() for the portable target (volpath_native/kernel_target.py): only
# cache entries compiled for it are shipped.
PORTABLE_MAGIC = ("x86_64-unknown-linux-gnu", "generic", "")
_STAGE_IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc", "build_extension.py")


class BuildError(RuntimeError):
    pass


def _run(cmd, **kwargs) -> subprocess.CompletedProcess:
    print("+", " ".join(str(c) for c in cmd), flush=True)
    proc = subprocess.run([str(c) for c in cmd], text=True, capture_output=True, **kwargs)
    if proc.returncode != 0:
        raise BuildError(f"command failed ({proc.returncode}): {' '.join(map(str, cmd))}\n"
                         f"{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}")
    return proc


def read_manifest() -> dict:
    with open(MANIFEST, "rb") as f:
        return tomllib.load(f)


def blender_ext_cli() -> Path:
    """Blender's extension command line, shipped inside the bpy wheel."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise BuildError("the bpy module is not installed in this Python (run `make venv`)")
    for location in spec.submodule_search_locations:
        found = sorted(Path(location).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return found[-1]
    raise BuildError("blender_ext.py not found in the bpy package")


# ----------------------------------------------------------------------------------------------
# Wheels
# ----------------------------------------------------------------------------------------------
def _wheel_fields(filename: str):
    """(distribution, version, python tag, platform tags) of a wheel file name (PEP 427)."""
    parts = filename[:-len(".whl")].split("-")
    if len(parts) not in (5, 6):
        raise BuildError(f"not a wheel file name: {filename}")
    return parts[0], parts[1], parts[-3], parts[-1].split(".")


def build_wheels() -> list[Path]:
    """The wheels the manifest lists, in wheels/ (volpath_native rebuilt every time)."""
    WHEEL_DIR.mkdir(exist_ok=True)
    wheels = []
    for entry in read_manifest().get("wheels", []):
        target = WHEEL_DIR / Path(entry).name
        name, version, python_tag, platforms = _wheel_fields(target.name)
        if name == "volpath_native":
            target.unlink(missing_ok=True)
            _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
                  "-w", WHEEL_DIR, ROOT / "native"])
            if target.exists():
                ship_kernels(target, build_kernel_cache(target))
        elif not target.exists():
            cmd = [sys.executable, "-m", "pip", "download", "-q", "--only-binary", ":all:", "--no-deps",
                   "-d", WHEEL_DIR, f"{name}=={version}"]
            match = re.fullmatch(r"cp(\d)(\d+)", python_tag)
            if match:
                cmd += ["--python-version", f"{match.group(1)}.{match.group(2)}"]
            for platform in platforms:
                cmd += ["--platform", platform]
            _run(cmd)
        if not target.exists():
            raise BuildError(f"{target.name} was not produced; is the version in blender_manifest.toml right?")
        wheels.append(target)
    return wheels


# ----------------------------------------------------------------------------------------------
# Compiled kernels shipped in the volpath_native wheel
# ----------------------------------------------------------------------------------------------
_KERNEL_CHILD = """
import sys
sys.path.insert(0, sys.argv[1])
import volpath_native
from volpath_native import jit, kernel_target
assert volpath_native.__file__.startswith(sys.argv[1]), volpath_native.__file__
assert kernel_target.CPU_NAME == "generic", kernel_target.CPU_NAME
seconds = volpath_native.warm_up(thorough=True)
print("VOLPATH_KERNELS", jit.CACHE_KEY, jit.KERNEL_CACHE_DIR, round(seconds, 1))
"""


def build_kernel_cache(wheel: Path) -> Path:
    """Compile the wheel's kernels for the portable CPU target, by warming them up in a child
    Python that imports the wheel's own copy (so the cache key, a hash of the sources, is the one
    an installed copy computes). The cache goes to $NUMBA_CACHE_DIR (default
    ~/.cache/volpath/numba, where the renderer's own runs put it): an unchanged source tree whose
    kernels the tests or a render already compiled is reused in seconds; after an edit this
    compiles every kernel (minutes). Returns the cache folder of these sources."""
    import numba  # the build Python's numba compiles: it must be the one the manifest ships

    shipped = [Path(w).name for w in read_manifest().get("wheels", []) if Path(w).name.startswith("numba-")]
    if shipped and _wheel_fields(shipped[0])[1] != numba.__version__:
        raise BuildError(f"this Python has numba {numba.__version__} but the extension ships {shipped[0]}: "
                         "the compiled kernels would not be used (run `make venv`)")
    site = KERNEL_BUILD_DIR / "site"
    if site.exists():
        shutil.rmtree(site)
    site.mkdir(parents=True)
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(site)
    env = dict(os.environ, NUMBA_CPU_NAME="generic")
    env.pop("NUMBA_CPU_FEATURES", None)
    env.pop("VOLPATH_KERNEL_CPU", None)
    env.setdefault("NUMBA_CACHE_DIR", os.path.join(os.path.expanduser("~"), ".cache", "volpath", "numba"))
    print("compiling the render kernels for the portable CPU target (minutes after a source change)", flush=True)
    out = _run([sys.executable, "-c", _KERNEL_CHILD, site], env=env, cwd=KERNEL_BUILD_DIR).stdout
    match = re.search(r"VOLPATH_KERNELS (\S+) (.+) (\S+)$", out, re.MULTILINE)
    if not match:
        raise BuildError(f"the kernel warm-up printed no cache folder:\n{out[-2000:]}")
    print(f"kernels ready in {match.group(3)} s: {match.group(2)}")
    return Path(match.group(2).strip())


def portable_entries(cache: Path) -> dict[Path, bytes]:
    """{path relative to `cache`: bytes} of the cache's indexes rewritten to hold only the entries
    compiled for the portable target, and their data files (a cache folder may also hold entries
    for this machine's CPU, compiled with VOLPATH_KERNEL_CPU=host)."""
    from numba.core.serialize import dumps  # what numba writes its indexes with

    files = {}
    for index in sorted(cache.rglob("*.nbi")):
        with open(index, "rb") as f:
            version = pickle.load(f)  # numba's version, then the pickled (stamp, overloads)
            stamp, overloads = pickle.loads(f.read())
        kept = {key: name for key, name in overloads.items() if tuple(key[1]) == PORTABLE_MAGIC}
        if not kept:
            continue
        relative = index.relative_to(cache)
        files[relative] = pickle.dumps(version, protocol=-1) + dumps((stamp, kept))
        for name in kept.values():
            files[relative.parent / name] = (index.parent / name).read_bytes()
    return files


def ship_kernels(wheel: Path, cache: Path) -> int:
    """Add the portable entries of `cache` to the wheel as volpath_native/prebuilt_kernels/<key>/
    (jit.PREBUILT_DIR), with their lines in the wheel's RECORD. Returns the bytes added."""
    files = portable_entries(cache)
    if not files:
        raise BuildError(f"no kernels compiled for the portable CPU target in {cache}")
    prefix = f"volpath_native/prebuilt_kernels/{cache.name}/"
    rebuilt = wheel.with_suffix(".tmp")
    with zipfile.ZipFile(wheel) as source, zipfile.ZipFile(rebuilt, "w", zipfile.ZIP_DEFLATED) as target:
        record_name = next(n for n in source.namelist() if n.endswith(".dist-info/RECORD"))
        record = source.read(record_name).decode()
        for item in source.infolist():
            if item.filename != record_name and not item.filename.startswith("volpath_native/prebuilt_kernels/"):
                target.writestr(item, source.read(item))
        lines = [line for line in record.splitlines() if line and not line.startswith("volpath_native/prebuilt_kernels/")]
        for relative, data in sorted(files.items()):
            name = prefix + relative.as_posix()
            target.writestr(name, data)
            digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            lines.append(f"{name},sha256={digest},{len(data)}")
        target.writestr(record_name, "\n".join(lines) + "\n")
    os.replace(rebuilt, wheel)
    size = sum(len(d) for d in files.values())
    print(f"shipped {sum(1 for p in files if p.suffix == '.nbi')} compiled kernels ({size / 1e6:.1f} MB) in {wheel.name}")
    return size


# ----------------------------------------------------------------------------------------------
# Extension zip
# ----------------------------------------------------------------------------------------------
def stage(wheels: list[Path]) -> Path:
    if STAGE_DIR.exists():
        shutil.rmtree(STAGE_DIR)
    shutil.copytree(ADDON_DIR, STAGE_DIR, ignore=_STAGE_IGNORE)
    shutil.copy2(MANIFEST, STAGE_DIR / MANIFEST.name)
    (STAGE_DIR / "wheels").mkdir()
    for wheel in wheels:
        shutil.copy2(wheel, STAGE_DIR / "wheels" / wheel.name)
    return STAGE_DIR


def build() -> Path:
    source = stage(build_wheels())
    DIST_DIR.mkdir(exist_ok=True)
    manifest = read_manifest()
    output = DIST_DIR / f"{manifest['id']}-{manifest['version']}.zip"
    output.unlink(missing_ok=True)
    _run([sys.executable, blender_ext_cli(), "build", "--source-dir", source, "--output-filepath", output])
    print(f"built {output}")
    return output


def validate(path: Path) -> None:
    _run([sys.executable, blender_ext_cli(), "validate", path])
    print(f"valid: {path}")


# ----------------------------------------------------------------------------------------------
# Installation into a Blender executable
# ----------------------------------------------------------------------------------------------
def blender_version(blender: str) -> tuple[int, int]:
    out = _run([blender, "--version"]).stdout
    match = re.search(r"Blender (\d+)\.(\d+)", out)
    if not match:
        raise BuildError(f"cannot read the version of {blender}:\n{out[:500]}")
    return int(match.group(1)), int(match.group(2))


def _blender_python(blender: str, expression: str, factory: bool = False) -> str:
    cmd = [blender, "-b"] + (["--factory-startup"] if factory else []) + [
        "--python-exit-code", "1", "--python-expr", expression]
    return _run(cmd).stdout


def install(blender: str) -> None:
    version = blender_version(blender)
    if version >= EXTENSION_MIN_VERSION:
        zip_path = build()
        _run([blender, "--command", "extension", "install-file", "-r", "user_default", "-e", zip_path])
        print(f"installed {zip_path.name} as an extension into Blender {version[0]}.{version[1]}")
        return
    install_legacy(blender, version)


def install_legacy(blender: str, version) -> None:
    wheels = build_wheels()
    out = _blender_python(blender, "import bpy; print('VOLPATH_SCRIPTS=' + bpy.utils.user_resource('SCRIPTS'))",
                          factory=True)
    match = re.search(r"VOLPATH_SCRIPTS=(.+)", out)
    if not match:
        raise BuildError(f"could not find Blender's user scripts folder:\n{out[-2000:]}")
    addons = Path(match.group(1).strip()) / "addons"
    target = addons / LEGACY_MODULE
    if target.exists():
        shutil.rmtree(target)
    shutil.copytree(ADDON_DIR, target, ignore=_STAGE_IGNORE)
    modules = addons / "modules"
    modules.mkdir(parents=True, exist_ok=True)
    _run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--upgrade", "--target", modules, *wheels])
    # Enable and save the preferences so that later `blender -b FILE -E VOLPATH` runs find it, and
    # compile a trivial numba function there: llvmlite must work inside this Blender process.
    out = _blender_python(blender, (
        "import addon_utils, bpy\n"
        f"addon_utils.enable('{LEGACY_MODULE}', default_set=True, persistent=True, handle_error=None)\n"
        f"assert '{LEGACY_MODULE}' in bpy.context.preferences.addons, 'add-on did not enable'\n"
        "bpy.ops.wm.save_userpref()\n"
        "import numba\n"
        "assert numba.njit(lambda x: x + 1)(1) == 2\n"
        "print('VOLPATH_NUMBA=' + numba.__version__ + ' ' + numba.__file__)\n"
        "print('VOLPATH_ENABLED')"))
    if "VOLPATH_ENABLED" not in out:
        raise BuildError(f"enabling the add-on failed:\n{out[-3000:]}")
    numba_found = re.search(r"VOLPATH_NUMBA=(\S+) (.+)", out)
    if numba_found and Path(numba_found.group(2).strip()).resolve().parents[1] != modules.resolve():
        # Blender's Python searches its own site-packages (e.g. Debian's python3-numba) first.
        print(f"warning: this Blender imports numba {numba_found.group(1)} from "
              f"{numba_found.group(2).strip()}, not the bundled one in {modules}", file=sys.stderr)
    print(f"installed the legacy add-on '{LEGACY_MODULE}' into {addons} (Blender {version[0]}.{version[1]})")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("build", help="build dist/volpath-<version>.zip")
    check = sub.add_parser("validate", help="validate a built zip or a staged directory")
    check.add_argument("path", nargs="?", type=Path)
    inst = sub.add_parser("install", help="install into a Blender executable")
    inst.add_argument("--blender", required=True)
    args = parser.parse_args(argv)
    try:
        if args.command == "build":
            validate(build())
        elif args.command == "validate":
            validate(args.path or build())
        else:
            install(args.blender)
    except BuildError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
