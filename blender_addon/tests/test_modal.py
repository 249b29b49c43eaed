"""The interactive path: invoke starts the CLI and returns at once, timer events poll it, Esc kills it.

bpy-as-a-module has no event loop, so the operator's own methods (jobs.JobOperator mixed into
the real operator's prepare/finish) are driven here with a stand-in window manager, area and
workspace that record timers and status text; everything else is the real bpy context.
"""
import os
import time

import pytest


class Event:
    def __init__(self, type, value="NOTHING"):
        self.type, self.value = type, value


class Recorder:
    def __init__(self):
        self.status, self.header, self.timers, self.handlers = [], [], [], []
        self.windows = []

    # window manager
    def event_timer_add(self, step, window=None):
        self.timers.append(("timer", step))
        return self.timers[-1]

    def event_timer_remove(self, timer):
        self.timers.remove(timer)

    def modal_handler_add(self, op):
        self.handlers.append(op)

    # workspace / area
    def status_text_set(self, text):
        self.status.append(text)

    def header_text_set(self, text):
        self.header.append(text)


class Context:
    def __init__(self, real, rec):
        self._real, self.window, self.window_manager, self.workspace, self.area = real, object(), rec, rec, rec

    def __getattr__(self, name):
        return getattr(self._real, name)


def modal_operator(addon, op_class, **props):
    """An instance of `op_class`'s behaviour outside Blender's operator system."""
    body = {k: v for k, v in vars(op_class).items() if callable(v) and not k.startswith("__")}
    cls = type(f"Modal{op_class.__name__}", (addon.jobs.JobOperator,), body)
    op = cls()
    op.reports = []
    op.report = lambda kind, msg: op.reports.append((set(kind), msg))
    for k, v in props.items():
        setattr(op, k, v)
    return op


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False


def test_modal_preview_returns_at_once_and_finishes_on_a_timer(bpy_module, addon, scene):
    bpy = bpy_module
    rec = Recorder()
    ctx = Context(bpy.context, rec)
    op = modal_operator(addon, addon.operators.PRISMBAKE_OT_preview)
    assert op.invoke_modal(ctx) == {"RUNNING_MODAL"}
    assert rec.handlers == [op] and len(rec.timers) == 1
    assert rec.status[-1].startswith("prismbake render: ") and "Esc to cancel" in rec.status[-1]
    # While it runs, no second job may start, and the UI says why.
    assert not bpy.ops.prismbake.bake.poll()
    with pytest.raises(RuntimeError, match="a prismbake job is running"):
        bpy.ops.prismbake.bake()
    slowest, ticks = 0.0, 0
    deadline = time.monotonic() + 60
    while True:
        t0 = time.perf_counter()
        outcome = op.modal(ctx, Event("TIMER"))
        slowest = max(slowest, time.perf_counter() - t0) if outcome == {"PASS_THROUGH"} else slowest
        if outcome != {"PASS_THROUGH"}:
            break
        ticks += 1
        assert op.modal(ctx, Event("MOUSEMOVE")) == {"PASS_THROUGH"}  # other events go on to the UI
        assert time.monotonic() < deadline
        time.sleep(0.02)
    assert outcome == {"FINISHED"}, op.reports
    assert ticks >= 1 and slowest < 0.1, f"a timer tick blocked the UI for {slowest:.3f} s"
    assert rec.timers == [] and rec.status[-1] is None and rec.header[-1] is None
    assert "prismbake preview: Sphere" in bpy.data.images
    assert any("Preview of Sphere" in msg for kind, msg in op.reports if kind == {"INFO"})
    assert addon.jobs.RUNNING == {}


def test_esc_kills_the_cli_and_cancels(bpy_module, addon, scene, prefs, tmp_path):
    bpy = bpy_module
    prefs.resolution = 256
    rec = Recorder()
    ctx = Context(bpy.context, rec)
    out = tmp_path / "long"
    op = modal_operator(addon, addon.operators.PRISMBAKE_OT_turntable, frames=2000, directory=str(out))
    assert op.invoke_modal(ctx) == {"RUNNING_MODAL"}
    pid = op._job.pid
    deadline = time.monotonic() + 60
    while not any(n.startswith("normal_") for n in os.listdir(out)):  # it is really rendering
        assert op.modal(ctx, Event("TIMER")) == {"PASS_THROUGH"}
        assert time.monotonic() < deadline
        time.sleep(0.05)
    op.modal(ctx, Event("TIMER"))
    assert "frame" in rec.status[-1] and "/2000" in rec.status[-1]
    t0 = time.monotonic()
    assert op.modal(ctx, Event("ESC", "PRESS")) == {"CANCELLED"}
    assert time.monotonic() - t0 < 5
    assert not _alive(pid)
    assert op.reports == [({"WARNING"}, "prismbake render was cancelled")]
    assert addon.jobs.RUNNING == {} and rec.timers == [] and rec.status[-1] is None
    frames = len([n for n in os.listdir(out) if n.startswith("normal_") and n.endswith(".png")])
    assert frames < 2000
    time.sleep(0.3)
    assert len([n for n in os.listdir(out) if n.startswith("normal_") and n.endswith(".png")]) == frames


def test_modal_cli_error_is_reported_when_it_arrives(bpy_module, addon, scene, tmp_path):
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"\x89PNG but not really")
    scene.active_material.node_tree.nodes["Image Texture"].image.filepath = str(broken)
    rec = Recorder()
    ctx = Context(bpy_module.context, rec)
    op = modal_operator(addon, addon.operators.PRISMBAKE_OT_preview)
    assert op.invoke_modal(ctx) == {"RUNNING_MODAL"}
    deadline = time.monotonic() + 30
    while (outcome := op.modal(ctx, Event("TIMER"))) == {"PASS_THROUGH"}:
        assert time.monotonic() < deadline
        time.sleep(0.02)
    assert outcome == {"CANCELLED"}
    [(kind, msg)] = op.reports
    assert kind == {"ERROR"} and msg.startswith("prismbake render failed (input or I/O error, exit 2): ")
    assert "broken.png" in msg
