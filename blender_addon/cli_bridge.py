"""The add-on's only contact with the `prismbake` CLI: no bpy here.

It finds the binary, builds argument lists from plain settings, runs them as a subprocess
that can be polled (so Blender's UI never blocks) or waited for, and turns the CLI's JSON,
stderr and exit codes into plain results and one-line messages a user can act on.
Exit codes follow the CLI: 0 success, 1 problems found (validate), 2 usage/input/I-O error.
"""
from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import tempfile
import time
from typing import Optional, Sequence

EXIT_OK = 0
EXIT_PROBLEMS = 1
EXIT_ERROR = 2

METHODS = ("pdm", "reference")
DEVICES = ("cpu", "gpu", "auto")


class BridgeError(Exception):
    """A problem found before or after running the CLI, with a message for the user."""


# --- finding the binary --------------------------------------------------------------------

def find_binary(configured: str = "") -> tuple[Optional[str], str]:
    """(path, "") for a runnable binary, else (None, why): the configured path, else PATH."""
    if configured:
        path = os.path.abspath(os.path.expanduser(configured))
        if os.path.isdir(path):
            return None, f"prismbake binary path {path} is a folder: point it at the executable"
        if not os.path.isfile(path):
            return None, f"prismbake binary not found at {path}: fix the path in the add-on preferences"
        if not os.access(path, os.X_OK):
            return None, f"prismbake binary {path} is not executable (chmod +x it)"
        return path, ""
    found = shutil.which("prismbake")
    if found is None:
        return None, ("prismbake is not on PATH: install it (./install.sh) or set its path "
                      "in the add-on preferences")
    return found, ""


def has_command(binary: str, command: str, timeout: float = 10.0) -> bool:
    """Whether `prismbake --help` lists `command` (e.g. `export`, added after the others)."""
    try:
        out = subprocess.run([binary, "--help"], capture_output=True, text=True, timeout=timeout)
    except (OSError, subprocess.TimeoutExpired):
        return False
    in_commands = False
    for line in out.stdout.splitlines():
        if line.strip().lower().startswith("commands:"):
            in_commands = True
            continue
        if in_commands:
            if not line.startswith(" "):
                break
            if line.split() and line.split()[0] == command:
                return True
    return False


# --- settings and argument lists -----------------------------------------------------------

@dataclasses.dataclass
class Displacement:
    """What the CLI needs to displace a mesh: `D = scale * (h - midlevel)` in world units."""
    image_path: str
    scale: float
    midlevel: float
    uv_set: int = 0
    wrap: Optional[str] = None  # "repeat" | "clamp" | None (CLI default)

    def args(self) -> list[str]:
        out = ["--disp", self.image_path, "--scale", _num(self.scale), "--midlevel", _num(self.midlevel)]
        if self.uv_set:
            out += ["--uv-set", str(self.uv_set)]
        if self.wrap:
            out += ["--wrap", self.wrap]
        return out


@dataclasses.dataclass
class RenderSettings:
    method: str = "pdm"
    device: str = "cpu"
    resolution: int = 256
    samples: int = 1
    aovs: Sequence[str] = ("normal", "mask")

    def args(self) -> list[str]:
        if self.method not in METHODS:
            raise BridgeError(f"unknown method {self.method!r}: use one of {', '.join(METHODS)}")
        if self.device not in DEVICES:
            raise BridgeError(f"unknown device {self.device!r}: use one of {', '.join(DEVICES)}")
        if self.resolution < 1 or self.samples < 1:
            raise BridgeError("resolution and samples must be at least 1")
        return ["--method", self.method, "--device", self.device,
                "--res", f"{self.resolution}x{self.resolution}", "--spp", str(self.samples),
                "--aov", ",".join(self.aovs)]


def _num(x: float) -> str:
    # repr keeps every digit of a Python float; the CLI parses Rust floats, which accept it.
    return repr(float(x))


def render_args(binary: str, mesh: str, disp: Displacement, settings: RenderSettings,
                out_dir: str, turntable: int = 0) -> list[str]:
    argv = [binary, "render", mesh, *disp.args(), *settings.args(), "-o", out_dir, "--json"]
    if turntable:
        if turntable < 1:
            raise BridgeError("a turntable needs at least 1 frame")
        argv[-1:-1] = ["--turntable", str(turntable)]
    return argv


def bake_args(binary: str, mesh: str, disp: Displacement, out: str, force: bool = False) -> list[str]:
    argv = [binary, "bake", mesh, *disp.args(), "-o", out, "--json"]
    if force:
        argv.append("--force")
    return argv


def validate_args(binary: str, mesh: str, disp: Displacement, max_disp: float = 0.0,
                  max_seam_jump: Optional[float] = None) -> list[str]:
    argv = [binary, "validate", mesh, *disp.args(), "--format", "json"]
    if max_disp > 0:
        argv += ["--max-disp", _num(max_disp)]
    if max_seam_jump is not None:
        argv += ["--max-seam-jump", _num(max_seam_jump)]
    return argv


def export_usd_args(binary: str, mesh: str, disp: Displacement, out: str) -> list[str]:
    return [binary, "export", mesh, *disp.args(), "--usd", out]


# --- results -------------------------------------------------------------------------------

@dataclasses.dataclass
class CliResult:
    argv: list[str]
    returncode: int
    stdout: str
    stderr: str
    seconds: float
    cancelled: bool = False

    @property
    def command(self) -> str:
        return self.argv[1] if len(self.argv) > 1 else "prismbake"

    def ok(self, allowed: Sequence[int] = (EXIT_OK,)) -> bool:
        return not self.cancelled and self.returncode in allowed

    def error_message(self) -> str:
        """One line that says which command failed and why (the CLI's own error line)."""
        if self.cancelled:
            return f"prismbake {self.command} was cancelled"
        line = last_error_line(self.stderr)
        if self.returncode < 0:
            why = f"killed by signal {-self.returncode}"
            return f"prismbake {self.command} {why}" + (f": {line}" if line else "")
        meaning = {EXIT_PROBLEMS: "problems found", EXIT_ERROR: "input or I/O error"}.get(
            self.returncode, "crashed" if self.returncode == 101 else "failed")
        if not line:
            line = "no message on stderr"
        return f"prismbake {self.command} failed ({meaning}, exit {self.returncode}): {line}"

    def json(self) -> dict:
        try:
            data = json.loads(self.stdout)
        except json.JSONDecodeError as e:
            raise BridgeError(f"prismbake {self.command} printed no valid JSON ({e}); "
                              f"is the binary too old for this add-on?") from None
        if not isinstance(data, dict):
            raise BridgeError(f"prismbake {self.command} printed JSON that is not an object")
        return data


def last_error_line(stderr: str) -> str:
    """The CLI's error line (`error: ...` without the prefix), else a panic line, else the last."""
    lines = [l.strip() for l in stderr.splitlines() if l.strip()]
    for l in reversed(lines):
        if l.lower().startswith("error:"):
            return l[len("error:"):].strip()
    for l in lines:
        if "panicked at" in l:
            return l
    return lines[-1] if lines else ""


@dataclasses.dataclass
class RenderSummary:
    files: list[str]
    seconds: float
    coverage: Optional[float]
    frames: int
    method: str
    device: str
    # `--device auto` only: why the GPU could not render the job, which the CPU then rendered.
    gpu_fallback: Optional[str] = None

    def device_note(self) -> str:
        """What an artist is told besides the timing: nothing, or that the CPU stood in."""
        if not self.gpu_fallback:
            return ""
        return f"; rendered on the CPU: {self.gpu_fallback}"

    def first(self, aov: str, ext: str = ".png") -> Optional[str]:
        for f in self.files:
            base = os.path.basename(f)
            if base.startswith(aov) and base.endswith(ext):
                return f
        return None


def parse_render(data: dict) -> RenderSummary:
    frames = data.get("frames") or []
    cov = frames[0].get("coverage") if frames and isinstance(frames[0], dict) else None
    return RenderSummary(
        files=[str(f) for f in data.get("files") or []],
        seconds=float(data.get("setup_seconds") or 0.0)
        + sum(float(f.get("seconds") or 0.0) for f in frames if isinstance(f, dict)),
        coverage=cov, frames=len(frames),
        method=str(data.get("method", "")), device=str(data.get("device", "")),
        gpu_fallback=data.get("gpu_fallback") or None)


@dataclasses.dataclass
class Problem:
    asset: str
    check: str
    status: str
    message: str
    faces: list[int]
    # Seam edges, as the pair of triangles on their two sides (the `seam-jump` check).
    seam_edges: list[tuple[int, int]] = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class ValidateReport:
    problems: list[Problem]
    passed: list[str]
    failed_assets: int
    mesh_triangles: Optional[int] = None  # from the `mesh` check: checks a face map

    @property
    def faces(self) -> list[int]:
        """Faces of every problem except those only named as the sides of a seam edge."""
        out: set[int] = set()
        for p in self.problems:
            if not p.seam_edges:
                out.update(p.faces)
        return sorted(out)

    @property
    def seam_edges(self) -> list[tuple[int, int]]:
        return [e for p in self.problems for e in p.seam_edges]


def parse_validate(data: dict) -> ValidateReport:
    problems, passed, tris = [], [], None
    for asset in data.get("assets") or []:
        for c in asset.get("checks") or []:
            name, status = str(c.get("name", "")), str(c.get("status", ""))
            if name == "mesh":
                tris = _leading_int(str(c.get("message", "")))
            if status == "pass":
                passed.append(name)
            else:
                problems.append(Problem(str(asset.get("asset", "")), name, status,
                                        str(c.get("message", "")),
                                        [int(f) for f in c.get("faces") or []],
                                        [(int(a), int(b)) for a, b in c.get("seam_edges") or []]))
    failed = int((data.get("summary") or {}).get("failed", 0))
    return ValidateReport(problems, passed, failed, mesh_triangles=tris)


def _leading_int(text: str) -> Optional[int]:
    head = text.split(" ", 1)[0]
    return int(head) if head.isdigit() else None


def triangles_to_polygons(faces: Sequence[int], tri_to_poly: Sequence[int]) -> tuple[list[int], list[int]]:
    """Polygons of the CLI's triangle indices, and the indices that fall outside the map."""
    polys, outside = set(), []
    for f in faces:
        if 0 <= f < len(tri_to_poly):
            polys.add(tri_to_poly[f])
        else:
            outside.append(f)
    return sorted(polys), outside


def seam_edges_to_polygon_pairs(edges: Sequence[tuple[int, int]],
                                tri_to_poly: Sequence[int]) -> tuple[list[tuple[int, int]], list[int]]:
    """Polygon pairs of the CLI's seam edges (pairs of triangles), and the triangle indices
    that fall outside the map. Pairs inside one polygon cannot be seams and are dropped."""
    pairs, outside = [], []
    for a, b in edges:
        if not (0 <= a < len(tri_to_poly) and 0 <= b < len(tri_to_poly)):
            outside += [f for f in (a, b) if not 0 <= f < len(tri_to_poly)]
            continue
        pa, pb = tri_to_poly[a], tri_to_poly[b]
        if pa != pb and (pa, pb) not in pairs:
            pairs.append((pa, pb))
    return pairs, outside


# --- running -------------------------------------------------------------------------------

class CliJob:
    """One CLI run in the background: `start()`, then `poll()` from a timer or `wait()`.

    stdout and stderr go to temporary files, not pipes, so a chatty process can never block
    on a full pipe while nobody reads it. `cancel()` kills the process (and its children on
    POSIX, through its own process group).
    """

    def __init__(self, argv: Sequence[str], cwd: Optional[str] = None):
        self.argv = [str(a) for a in argv]
        self.cwd = cwd
        self._proc: Optional[subprocess.Popen] = None
        self._out = self._err = None
        self._started = 0.0
        self._cancelled = False
        self.result: Optional[CliResult] = None

    @property
    def pid(self) -> Optional[int]:
        return self._proc.pid if self._proc else None

    def start(self) -> "CliJob":
        self._out = tempfile.TemporaryFile(mode="w+b")
        self._err = tempfile.TemporaryFile(mode="w+b")
        self._started = time.monotonic()
        kwargs = {}
        if os.name == "posix":
            kwargs["start_new_session"] = True
        try:
            self._proc = subprocess.Popen(self.argv, stdout=self._out, stderr=self._err,
                                          stdin=subprocess.DEVNULL, cwd=self.cwd, **kwargs)
        except OSError as e:
            self._close()
            raise BridgeError(f"cannot run {self.argv[0]}: {e.strerror or e}") from None
        return self

    def elapsed(self) -> float:
        return time.monotonic() - self._started if self._started else 0.0

    def poll(self) -> Optional[CliResult]:
        """None while running, else the result (also kept in `self.result`)."""
        if self.result is not None:
            return self.result
        if self._proc is None:
            raise BridgeError("the job was not started")
        code = self._proc.poll()
        if code is None:
            return None
        return self._finish(code)

    def wait(self, timeout: Optional[float] = None) -> CliResult:
        if self.result is not None:
            return self.result
        if self._proc is None:
            raise BridgeError("the job was not started")
        try:
            code = self._proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.cancel()
            raise BridgeError(f"prismbake {self.argv[1]} took longer than {timeout:.0f} s and was stopped") from None
        return self._finish(code)

    def cancel(self) -> CliResult:
        """Kill the process if it still runs; the result says `cancelled`."""
        if self.result is not None:
            return self.result
        if self._proc is None:
            raise BridgeError("the job was not started")
        self._cancelled = self._proc.poll() is None
        if self._cancelled:
            self._kill()
        return self._finish(self._proc.wait())

    def _kill(self) -> None:
        proc = self._proc
        try:
            if os.name == "posix":
                os.killpg(proc.pid, 9)
            else:
                proc.kill()
        except (ProcessLookupError, PermissionError, OSError):
            proc.kill()

    def _finish(self, code: int) -> CliResult:
        def read(f) -> str:
            f.seek(0)
            return f.read().decode("utf-8", errors="replace")
        self.result = CliResult(self.argv, code, read(self._out), read(self._err),
                                self.elapsed(), cancelled=self._cancelled)
        self._close()
        return self.result

    def _close(self) -> None:
        for f in (self._out, self._err):
            if f is not None:
                f.close()
        self._out = self._err = None


def count_files(folder: str, suffix: str, prefix: str = "", since: float = 0.0) -> int:
    """Files `prefix*suffix` in `folder` modified at or after `since`: a turntable's progress
    (one file per frame and AOV; older frames from an earlier run are not counted)."""
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0
    n = 0
    for e in entries:
        if e.name.startswith(prefix) and e.name.endswith(suffix) and not e.name.startswith("."):
            try:
                if e.stat().st_mtime >= since:
                    n += 1
            except OSError:
                pass
    return n


def progress_text(command: str, elapsed: float, done: int = 0, total: int = 0) -> str:
    frames = f", frame {min(done, total)}/{total}" if total else ""
    return f"prismbake {command}: {elapsed:.1f} s{frames} (Esc to cancel)"
