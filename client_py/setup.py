"""Build script of the `garmentdynamics` package.

The gRPC stubs are not kept in the repository: `build_py` runs grpc_tools.protoc on the
repository's proto/ (../proto from this file, or $GD_PROTO_DIR) and writes
garmentdynamics/v1/garmentdynamics_pb2.py and garmentdynamics_pb2_grpc.py. The proto's package is
`garmentdynamics.v1`, so the generated modules import each other as
`garmentdynamics.v1.garmentdynamics_pb2`, which is exactly where they land.

Regular installs get the stubs in the build directory; editable installs (`pip install -e`) get
them in the source tree (ignored by git), since that is where an editable install imports from.
Otherwise a build writes nothing into the source tree: the build directory and the egg-info go
under the system's temporary directory (`--build-base` / `--egg-base` still choose), and the
version probe of the stubs runs in a temporary directory of its own.
The versions of grpcio and protobuf the stubs need are read from the generated files and become
lower bounds of the dependencies, so an old runtime cannot meet newer generated code.
"""

import hashlib
import os
import re
import sys
import tempfile
from pathlib import Path

from setuptools import setup
from setuptools.command.build import build
from setuptools.command.build_py import build_py
from setuptools.command.egg_info import egg_info

HERE = Path(__file__).resolve().parent
PROTO_FILE = "garmentdynamics/v1/garmentdynamics.proto"


def proto_dir() -> Path:
    d = Path(os.environ.get("GD_PROTO_DIR", HERE.parent / "proto")).resolve()
    if not (d / PROTO_FILE).is_file():
        sys.exit(
            f"garmentdynamics: cannot find {PROTO_FILE} under {d}; build from a checkout of the "
            "repository (client_py/ next to proto/) or set GD_PROTO_DIR to the proto directory"
        )
    return d


def generate(out_root: Path) -> None:
    """Writes the stubs under out_root/garmentdynamics/v1 and the build info module."""
    from grpc_tools import protoc  # a build requirement (pyproject.toml)
    import grpc_tools

    src = proto_dir()
    out_root.mkdir(parents=True, exist_ok=True)
    include = Path(grpc_tools.__file__).resolve().parent / "_proto"  # google/protobuf/*.proto
    args = ["grpc_tools.protoc", f"-I{src}", f"-I{include}", f"--python_out={out_root}",
            f"--grpc_python_out={out_root}", str(src / PROTO_FILE)]
    if protoc.main(args) != 0:
        sys.exit(f"garmentdynamics: grpc_tools.protoc failed on {src / PROTO_FILE}")
    init = out_root / "garmentdynamics" / "v1" / "__init__.py"
    if not init.exists():
        init.write_text('"""Generated gRPC stubs of garmentdynamics.v1 (see setup.py)."""\n')
    repo = src.parent if (src.parent / "CMakeLists.txt").is_file() else None
    (out_root / "garmentdynamics" / "_build_info.py").write_text(
        '"""Written by setup.py at build time."""\n'
        f"PROTO_DIR = {str(src)!r}\n"
        f"REPO_ROOT = {str(repo) if repo else None!r}\n")


def runtime_requirements() -> list:
    """grpcio/protobuf lower bounds that match the code grpc_tools generates."""
    with tempfile.TemporaryDirectory(prefix="garmentdynamics-stub-probe-") as tmp:
        generate(Path(tmp))
        v1 = Path(tmp) / "garmentdynamics" / "v1"
        pb2 = (v1 / "garmentdynamics_pb2.py").read_text()
        grpc_py = (v1 / "garmentdynamics_pb2_grpc.py").read_text()
    reqs = ["numpy>=1.21"]
    m = re.search(r"ValidateProtobufRuntimeVersion\(\s*_runtime_version\.Domain\.PUBLIC,\s*(\d+),\s*(\d+),\s*(\d+)",
                  pb2)
    reqs.append(f"protobuf>={m.group(1)}.{m.group(2)}.{m.group(3)}" if m else "protobuf>=3.20")
    m = re.search(r"GRPC_GENERATED_VERSION\s*=\s*'([0-9.]+)'", grpc_py)
    reqs.append(f"grpcio>={m.group(1)}" if m else "grpcio>=1.50")
    return reqs


def out_of_tree(kind: str) -> str:
    """A directory for this build's `kind` outputs outside the source tree, per user and checkout."""
    tag = f"{os.getuid() if hasattr(os, 'getuid') else 0}-{hashlib.sha1(str(HERE).encode()).hexdigest()[:10]}"
    d = Path(tempfile.gettempdir()) / f"garmentdynamics-{kind}-{tag}"
    d.mkdir(parents=True, exist_ok=True)
    return str(d)


class BuildOutOfTree(build):
    """build whose default build directory is not client_py/build."""

    def initialize_options(self):
        super().initialize_options()
        self.build_base = out_of_tree("build")


class EggInfoOutOfTree(egg_info):
    """egg_info whose default directory is not the source tree."""

    def initialize_options(self):
        super().initialize_options()
        self.egg_base = out_of_tree("egg-info")


class BuildPyWithStubs(build_py):
    """build_py that also generates the gRPC stubs from the proto."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            generate(HERE)
        else:
            generate(Path(self.build_lib))

    def get_outputs(self, include_bytecode=True):
        outs = list(super().get_outputs(include_bytecode))
        if not getattr(self, "editable_mode", False):
            v1 = Path(self.build_lib) / "garmentdynamics" / "v1"
            outs += [str(v1 / "garmentdynamics_pb2.py"), str(v1 / "garmentdynamics_pb2_grpc.py"),
                     str(Path(self.build_lib) / "garmentdynamics" / "_build_info.py")]
        return outs


setup(install_requires=runtime_requirements(), cmdclass={"build": BuildOutOfTree, "build_py": BuildPyWithStubs,
                                                               "egg_info": EggInfoOutOfTree})
