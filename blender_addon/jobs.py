"""The operator base class: one CLI run per operator, modal (UI stays live) or waited for.

`invoke` (buttons, menus) starts the process and polls it from a window timer; the status
bar and the area header show the elapsed time (and frames for turntables); Esc kills the
process. `execute` (scripts, tests, the F3 "repeat") runs the same steps and waits. Either
way the subclass only says what to run (`prepare`) and what to do with the result (`finish`);
CLI failures become one `ERROR` report built by cli_bridge.
"""
from __future__ import annotations

import os
import time

import bpy

from . import cli_bridge, detect, prefs

# The one job running in this Blender session (operators refuse to start a second one).
RUNNING: dict = {}
# Last outcome per object name and operator, for the panel (plain data only).
RESULTS: dict = {}

_COMMANDS_CACHE: dict = {}


def binary_has_command(binary: str, command: str) -> bool:
    """`prismbake --help` lists `command`; cached per binary and modification time."""
    try:
        key = (binary, os.path.getmtime(binary), command)
    except OSError:
        return False
    if key not in _COMMANDS_CACHE:
        _COMMANDS_CACHE[key] = cli_bridge.has_command(binary, command)
    return _COMMANDS_CACHE[key]


def remember(obj_name: str, what: str, value) -> None:
    RESULTS.setdefault(obj_name, {})[what] = value


class JobOperator:
    """Mixin for bpy.types.Operator subclasses; see the module doc."""
    bl_options = {"REGISTER"}
    needs_displacement = True
    cli_command = ""              # a subcommand that must exist in the binary (e.g. "export")
    allowed_exit = (cli_bridge.EXIT_OK,)

    # --- what subclasses provide ---
    def prepare(self, context, binary: str, info: detect.DisplacementInfo) -> list:
        raise NotImplementedError

    def finish(self, context, result: cli_bridge.CliResult) -> set:
        raise NotImplementedError

    def progress(self) -> tuple:
        return 0, 0

    def cleanup(self) -> None:
        pass

    # --- poll ---
    @classmethod
    def why_not(cls, context) -> str:
        if RUNNING:
            return "a prismbake job is running: wait for it or press Esc to cancel it"
        binary, why = cli_bridge.find_binary(prefs.get(context).binary_path)
        if binary is None:
            return why
        if cls.cli_command and not binary_has_command(binary, cls.cli_command):
            return (f"this prismbake ({binary}) has no `{cls.cli_command}` command: "
                    f"update the binary")
        obj = context.active_object
        if obj is None or obj.type != "MESH":
            return "select a mesh object"
        if cls.needs_displacement:
            info = detect.detect(obj)
            if not info.ok:
                return info.problems[0]
        return ""

    @classmethod
    def poll(cls, context):
        why = cls.why_not(context)
        if why:
            cls.poll_message_set(why)
            return False
        return True

    # --- running ---
    def _begin(self, context) -> bool:
        """Gather everything and start the process; False (and an ERROR report) if it cannot."""
        self._t0 = time.perf_counter()
        context.view_layer.update()  # matrix_world of objects a script just moved
        binary, why = cli_bridge.find_binary(prefs.get(context).binary_path)
        obj = context.active_object
        if binary is None:
            self.report({"ERROR"}, why)
            return False
        info = detect.detect(obj)
        if self.needs_displacement and not info.ok:
            self.report({"ERROR"}, f"{obj.name}: " + "; ".join(info.problems))
            return False
        self._object_name = obj.name
        try:
            with _object_mode(context):
                argv = self.prepare(context, binary, info)
            self._job = cli_bridge.CliJob(argv).start()
        except cli_bridge.BridgeError as e:
            self.cleanup()
            self.report({"ERROR"}, str(e))
            return False
        except OSError as e:  # an output folder that cannot be made, a full temp disk
            self.cleanup()
            where = f" ({e.filename})" if e.filename else ""
            self.report({"ERROR"}, f"{self.bl_label}: {e.strerror or e}{where}")
            return False
        RUNNING["job"] = self._job
        return True

    def _end(self, context, result: cli_bridge.CliResult) -> set:
        RUNNING.pop("job", None)
        try:
            if not result.ok(self.allowed_exit):
                msg = result.error_message()
                remember(self._object_name, "error", msg)
                self.report({"WARNING"} if result.cancelled else {"ERROR"}, msg)
                return {"CANCELLED"}
            RESULTS.get(self._object_name, {}).pop("error", None)
            return self.finish(context, result)
        except cli_bridge.BridgeError as e:
            remember(self._object_name, "error", str(e))
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        finally:
            self.cleanup()

    def execute(self, context):
        if not self._begin(context):
            return {"CANCELLED"}
        try:
            result = self._job.wait(timeout=prefs.get(context).timeout)
        except cli_bridge.BridgeError as e:
            RUNNING.pop("job", None)
            self.cleanup()
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return self._end(context, result)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:  # no event loop to poll from
            return self.execute(context)
        return self.invoke_modal(context)

    def invoke_modal(self, context):
        if not self._begin(context):
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        self._area = context.area
        wm.modal_handler_add(self)
        self._show_progress(context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            return self._stop(context, self._job.cancel())
        if event.type == "TIMER":
            result = self._job.poll()
            if result is not None:
                return self._stop(context, result)
            self._show_progress(context)
        return {"PASS_THROUGH"}

    def _stop(self, context, result) -> set:
        context.window_manager.event_timer_remove(self._timer)
        self._set_status(context, None)
        outcome = self._end(context, result)
        for window in context.window_manager.windows:
            for area in window.screen.areas:
                area.tag_redraw()
        return outcome

    def _show_progress(self, context) -> None:
        done, total = self.progress()
        self._set_status(context, cli_bridge.progress_text(self._job.argv[1], self._job.elapsed(), done, total))

    def _set_status(self, context, text) -> None:
        if getattr(context, "workspace", None) is not None and hasattr(context.workspace, "status_text_set"):
            context.workspace.status_text_set(text)
        area = getattr(self, "_area", None)
        if area is not None:
            try:
                area.header_text_set(text)
            except ReferenceError:  # the area was closed while the job ran
                self._area = None


class _object_mode:
    """Export reads `obj.data`: leave Edit Mode for the export, come back afterwards."""

    def __init__(self, context):
        self.context = context
        self.was_edit = context.mode == "EDIT_MESH"

    def __enter__(self):
        if self.was_edit:
            bpy.ops.object.mode_set(mode="OBJECT")

    def __exit__(self, *exc):
        if self.was_edit:
            bpy.ops.object.mode_set(mode="EDIT")
        return False


def blend_relative(context, path_setting: str, default_name: str) -> str:
    """An absolute output path: the setting if set, else `default_name` next to the .blend."""
    if path_setting:
        return os.path.abspath(bpy.path.abspath(path_setting))
    if not bpy.data.filepath:
        raise cli_bridge.BridgeError("the .blend is not saved: save it, or choose an output path in "
                                     "the prismbake panel")
    return os.path.join(os.path.dirname(bpy.data.filepath), default_name)


def safe_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name) or "object"
