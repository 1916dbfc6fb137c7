"""The invalid calls of issue 9, each run between the calls of a valid sequence.

A case is a function ``case(model, ctx)`` returning the bad calls as ``(line, expect)`` pairs;
``expect`` is ``"refused"`` (fmi2Error or worse, with an error logged during the call),
``"refused_silent"`` (fmi2Error; there is no instance to log with), ``"discard"``, ``"ok"``
(fmi2OK or fmi2Warning: a call the standard allows, such as freeing a NULL state), or None
(either; what matters is what follows).  ``ctx`` holds the time, the inputs and the slot of the
instance at the point where the calls go, and the other model (for foreign states).

``WHERE[name]`` says where the calls go: ``instantiated`` (before fmi2SetupExperiment),
``init`` (initialisation mode, after the inputs are set), ``step`` (after initialisation, at
a random call of the sequence), ``end`` (after the sequence; the calls may terminate) or
``restart`` (after the sequence and the ``end`` cases: they reset the instance and
initialise it anew).  Cases in ``ALL_MODELS`` run
with each model; the others with the Accelerometer (which has every feature they need).
"""
import random
from dataclasses import dataclass

from . import DISCARD, ERROR, WARNING, Sequence, header, run_script, word

CASES = {}
WHERE = {}
ALL_MODELS = set()
#: Cases known to fail because of a bug on the Python side, with the bug; tests/test_fuzz.py
#: marks them xfail (none today: keep it empty).
PYTHON_SIDE = {}


def case(where, all_models=True, python_bug=None):
    def register(function):
        name = function.__name__
        CASES[name] = function
        WHERE[name] = where
        if all_models:
            ALL_MODELS.add(name)
        if python_bug:
            PYTHON_SIDE[name] = python_bug
        return function
    return register


@dataclass
class Context:
    slot: int
    t: float
    inputs: dict
    other: object  # the Model of another FMU, loaded as library 1, instance 6


def _outputs(model, slot):
    vrs = [model.vr[n] for n in model.outputs]
    return "getr %d %d %s" % (slot, len(vrs), " ".join(map(str, vrs)))


def _restore_inputs(model, ctx):
    return [("setr %d 1 %d %r" % (ctx.slot, model.vr[n], v), None)
            for n, v in ctx.inputs.items()]


# -- instantiation: resource locations, GUIDs, types, names ---------------------------------

def _inst(model, uri, guid=None, kind=1, name="bad"):
    return [("inst 5 0 %s %d %s %s" % (name, kind, model.guid if guid is None else guid, uri),
             "refused")]


@case("step", all_models=False)
def uri_null(model, ctx):
    return _inst(model, "NULL")


@case("step", all_models=False)
def uri_http(model, ctx):
    return _inst(model, "http://localhost%s/resources" % word(model.dir))


@case("step", all_models=False)
def uri_relative(model, ctx):
    return _inst(model, "resources") + _inst(model, "file:resources") + \
        _inst(model, "file:./resources")


@case("step", all_models=False)
def uri_other_host(model, ctx):
    return _inst(model, "file://fileserver%s/resources" % word(model.dir))


@case("step", all_models=False)
def uri_missing_folder(model, ctx):
    return _inst(model, "file://%s/no-such-folder" % word(model.dir)) + \
        _inst(model, "file:///no/such/folder/resources")


@case("step", all_models=False)
def uri_not_the_resources(model, ctx):
    return _inst(model, "file://%s" % word(model.dir)) + _inst(model, "file:///tmp")


@case("step", all_models=False)
def uri_bad_escapes(model, ctx):
    return _inst(model, "file://%s/resources%%zz" % word(model.dir)) + \
        _inst(model, "file://%s/res%%00ources" % word(model.dir)) + \
        _inst(model, "file://%s/resources%%" % word(model.dir))


@case("step", all_models=False)
def uri_very_long(model, ctx):
    return _inst(model, "file:///" + "a/" * 3000 + "resources") + \
        _inst(model, "file://" + word(model.dir) + "/" + "%41" * 5000)


@case("step", all_models=False)
def instance_name_very_long(model, ctx):
    """A name of 20,000 characters is accepted (nothing in the standard bounds it)."""
    return [("inst 5 0 %s 1 %s DEFAULT" % ("n" * 20000, model.guid), "ok"), ("free 5", None)]


@case("step", all_models=False)
def odd_callbacks(model, ctx):
    """No logger, no memory functions: the instance works (the shim logs nowhere, allocates
    with calloc); NULL callbacks: refused (there is nothing to log with)."""
    calls = []
    for kind in ("nolog", "noalloc"):
        calls += [("instcb 5 0 odd %s %s" % (model.guid, kind), "ok"), ("setup 5 0", "ok"),
                  ("enter 5", "ok"), ("exit 5", "ok"), ("step 5 0 %r" % model.Ts, "ok"),
                  ("setr 5 1 %d nan" % model.reals[0], "refused_silent"
                   if kind == "nolog" else "refused"), ("free 5", None)]
    return calls + [("instcb 5 0 odd %s null" % model.guid, "refused_silent")]


@case("step", all_models=False)
def guid_wrong(model, ctx):
    return _inst(model, "DEFAULT", guid="{00000000-0000-0000-0000-000000000000}") + \
        _inst(model, "DEFAULT", guid=model.guid.upper() + "x")


@case("step", all_models=False)
def guid_null(model, ctx):
    return _inst(model, "DEFAULT", guid="NULL")


@case("step", all_models=False)
def model_exchange(model, ctx):
    return _inst(model, "DEFAULT", kind=0) + _inst(model, "DEFAULT", kind=7)


@case("step", all_models=False)
def instance_name_null(model, ctx):
    return _inst(model, "DEFAULT", name="NULL")


# -- NULL pointers ----------------------------------------------------------------------------

@case("step")
def null_arrays(model, ctx):
    return [("null %d %s" % (ctx.slot, what), "refused")
            for what in ("getr_vr", "getr_value", "setr_vr", "setr_value", "geti_value")]


@case("step")
def null_state_arguments(model, ctx):
    return [("null %d %s" % (ctx.slot, what), "refused")
            for what in ("gst", "sst", "size", "size_out", "des_bytes", "des_state",
                         "status_value")]


@case("step")
def free_null_state(model, ctx):
    return [("null %d fst" % ctx.slot, "ok"), ("null %d fst_inner" % ctx.slot, "ok")]


@case("step")
def null_component(model, ctx):
    return [("null %d component" % ctx.slot, "refused_silent"),
            ("null %d component_get" % ctx.slot, "refused_silent")]


# -- FMU states -------------------------------------------------------------------------------

@case("step")
def state_garbage_pointer(model, ctx):
    i = ctx.slot
    return [("garbage 30", None), ("sst %d 30" % i, "refused"), ("fst %d 30" % i, "refused"),
            ("ser %d 30 30" % i, "refused")]


@case("step")
def state_get_into_garbage(model, ctx):
    i = ctx.slot
    return [("garbage 31", None), ("gst %d 31" % i, "ok"), ("fst %d 31" % i, "ok")]


@case("step")
def state_freed(model, ctx):
    i = ctx.slot
    return [("gst %d 32" % i, "ok"), ("alias 33 32", None), ("fst %d 32" % i, "ok"),
            ("sst %d 33" % i, "refused"), ("fst %d 33" % i, "refused")]


@case("step")
def state_foreign_pointer(model, ctx):
    i = ctx.slot
    return [("gst 6 34", "ok"), ("sst %d 34" % i, "refused"), ("fst %d 34" % i, "refused"),
            ("fst 6 34", "ok")]


@case("step")
def state_foreign_bytes(model, ctx):
    i = ctx.slot
    return [("gst 6 35", "ok"), ("ser 6 35 35", "ok"), ("des %d 35 36" % i, None),
            ("sst %d 36" % i, "refused"), ("fst %d 36" % i, None), ("fst 6 35", "ok")]


@case("step")
def state_garbage_bytes(model, ctx):
    i = ctx.slot
    calls = []
    for text in ("not-a-state", "{}", '{"k":\\s1}', "[1,2]", "", "\\n\\n"):
        calls += [("raw 37 %s" % text, None), ("des %d 37 38" % i, None),
                  ("sst %d 38" % i, "refused"), ("fst %d 38" % i, None)]
    return calls


def _instance(model, slot, name):
    """Calls that make an initialised instance in ``slot`` (each must succeed)."""
    return [("inst %d 0 %s 1 %s DEFAULT" % (slot, name, model.guid), "ok"),
            ("setup %d 0" % slot, "ok"), ("enter %d" % slot, "ok"), ("exit %d" % slot, "ok")]


@case("step", all_models=False)
def state_of_a_freed_instance(model, ctx):
    """A state got in an instance freed without freeing it dies with it: refused by this
    instance and by the one that takes the freed one's place (the Python FMUs' loader shim
    hands the same instance back)."""
    i = ctx.slot
    return _instance(model, 7, "ghost") + [
        ("gst 7 50", "ok"), ("free 7", None), ("sst %d 50" % i, "refused"),
        ("fst %d 50" % i, "refused")] + _instance(model, 7, "ghost") + [
        ("sst 7 50", "refused"), ("ser 7 50 50", "refused"), ("free 7", None)]


@case("step", all_models=False)
def state_of_another_instance(model, ctx):
    """A live state of another instance of the same FMU: refused (to move a state, serialise
    it), and left as it is."""
    i = ctx.slot
    return _instance(model, 7, "other") + [
        ("gst 7 51", "ok"), ("sst %d 51" % i, "refused"), ("fst %d 51" % i, "refused"),
        ("ser %d 51 51" % i, "refused"), ("gst %d 51" % i, "ok"), ("sst 7 51", "refused"),
        ("fst %d 51" % i, "ok"), ("free 7", None)]


@case("step", all_models=False)
def stop_time(model, ctx):
    """A stop time of 2.5 sample periods: steps to it are taken, a step past it is refused;
    stop times that cannot be are refused when given."""
    Ts = model.Ts
    guid = model.guid
    return [("inst 7 0 stop 1 %s DEFAULT" % guid, "ok"), ("setup 7 0 %r" % (2.5 * Ts), "ok"),
            ("enter 7", "ok"), ("exit 7", "ok"), ("step 7 0 %r" % Ts, "ok"),
            ("step 7 %r %r" % (Ts, Ts), "ok"), ("step 7 %r %r" % (2 * Ts, 2 * Ts), "refused"),
            ("step 7 %r %r" % (2 * Ts, Ts), "refused"),
            ("step 7 %r %r" % (2 * Ts, 0.5 * Ts), "ok"),
            ("step 7 %r %r" % (2.5 * Ts, Ts), "refused"), ("free 7", None),
            ("inst 7 0 stop 1 %s DEFAULT" % guid, "ok"), ("setup 7 1 0.5", "refused"),
            ("setup 7 0 nan", "refused"), ("setup 7 0 inf", "refused"), ("free 7", None)]


@case("step", all_models=False)
def count_impossible(model, ctx):
    """Gets and sets of every type with counts no array can have and one-element arrays."""
    return [("count %d %s %s" % (ctx.slot, kind, n), "refused")
            for kind in ("getr", "setr", "geti", "seti", "getb", "setb")
            for n in ("18446744073709551615", "2305843009213693952", "2147483648", "65537")]


def _crafted(model, ctx, key, value):
    i = ctx.slot
    return [("gst %d 40" % i, "ok"), ("ser %d 40 40" % i, "ok"),
            ("craft 40 41 %s %s" % (key, value), None), ("des %d 41 42" % i, None),
            ("sst %d 42" % i, None), ("fst %d 42" % i, None), ("fst %d 40" % i, "ok"),
            ("step %d %r %r" % (i, ctx.t, model.Ts), None), ("sst %d 40" % i, None)]


CRAFTED = {"call": ("_call", "0"), "method": ("get_real", "0"), "k_negative": ("k", "-1"),
           "k_string": ("k", '"x"'), "Ts_tiny": ("Ts", "2.2e-308"),
           "initialised": ("_initialised", '"yes"'), "class": ("__class__", "1"),
           "unknown": ("no_such_field", "1"), "nested": ("k", "[[[[1]]]]")}


def _crafted_case(tag, key, value):
    def crafted(model, ctx):
        # after the bad state the instance must be where it was: step once from there, then
        # go back (fmi2SetFMUstate of the saved state is what a master does after a failure)
        i = ctx.slot
        return [("gst %d 43" % i, "ok")] + _crafted(model, ctx, key, value)[:-2] + \
            [("sst %d 43" % i, "ok"), ("step %d %r %r" % (i, ctx.t, model.Ts), None),
             ("sst %d 43" % i, "ok"), ("fst %d 43" % i, "ok")]
    crafted.__name__ = "state_crafted_" + tag
    return crafted


for _tag, (_key, _value) in CRAFTED.items():
    case("step")(_crafted_case(_tag, _key, _value))


# -- step sizes and times ---------------------------------------------------------------------

@case("step")
def step_size_not_positive(model, ctx):
    return [("step %d %r %s" % (ctx.slot, ctx.t, h), "refused")
            for h in ("0", "-0", "-1e-3", "-inf")]


@case("step")
def step_size_not_finite(model, ctx):
    return [("step %d %r %s" % (ctx.slot, ctx.t, h), "refused") for h in ("nan", "inf")]


@case("step")
def step_size_huge(model, ctx):
    return [("step %d %r 1e300" % (ctx.slot, ctx.t), "refused"),
            ("step %d %r 1e12" % (ctx.slot, ctx.t), "refused")]


@case("step")
def step_time_not_finite(model, ctx):
    return [("step %d %s %r" % (ctx.slot, t, model.Ts), "refused") for t in ("nan", "inf")]


@case("init")
def sample_period_tiny(model, ctx):
    if "Ts" not in model.vr:
        return []
    i = ctx.slot
    return [("setr %d 1 %d 2.2e-308" % (i, model.vr["Ts"]), None), ("exit %d" % i, "refused"),
            ("setr %d 1 %d %r" % (i, model.vr["Ts"], model.Ts), None)]


# -- values that overflow ---------------------------------------------------------------------

#: Inputs that any finite value may take: the Excitation's u_in is passed to its output u (and
#: into x by B u, B = 0 here), so a huge value is a valid input that the step accepts.
PASS_THROUGH = {"Excitation": ("u_in",)}


@case("step")
def input_overflow(model, ctx):
    calls = []
    for name in [n for n in model.inputs if n not in PASS_THROUGH.get(model.name, ())]:
        for value in ("1e200", "-1e300", "1.7976931348623157e308"):
            calls += [("setr %d 1 %d %s" % (ctx.slot, model.vr[name], value), None),
                      (_outputs(model, ctx.slot), None),
                      ("step %d %r %r" % (ctx.slot, ctx.t, model.Ts), None)]
    return calls + _restore_inputs(model, ctx)


def _restart(model, ctx, parameters, inputs):
    """Reset, initialise with ``parameters`` and ``inputs``, read, step, read: any call may be
    refused, but none may crash or give fmi2OK with a non-finite value."""
    i = ctx.slot
    calls = [("reset %d" % i, "ok"), ("setup %d 0" % i, "ok"), ("enter %d" % i, "ok")]
    calls += [("setr %d 1 %d %s" % (i, model.vr[n], v), None) for n, v in parameters.items()]
    calls += [("setr %d 1 %d %s" % (i, model.vr[n], v), None) for n, v in inputs.items()]
    calls += [("exit %d" % i, None), (_outputs(model, i), None)]
    calls += [("step %d %r %r" % (i, k * model.Ts, model.Ts), None) for k in range(3)]
    return calls + [(_outputs(model, i), None)]


@case("restart", all_models=False)
def parameter_overflow(model, ctx):
    return _restart(model, ctx, {"a2": "1e308"}, {"x": "1.5"})


@case("restart", all_models=False)
def filtered_input_overflow(model, ctx):
    return _restart(model, ctx, {"fc": "100"}, {"x": "1e200"})


@case("step")
def input_not_finite(model, ctx):
    return [("setr %d 1 %d %s" % (ctx.slot, model.vr[name], value), "refused")
            for name in model.inputs for value in ("nan", "inf", "-inf")]


# -- calls out of order -----------------------------------------------------------------------

@case("instantiated")
def out_of_order_before_setup(model, ctx):
    i = ctx.slot
    return [("step %d 0 %r" % (i, model.Ts), "refused"), ("exit %d" % i, "refused"),
            (_outputs(model, i), "refused")]


@case("init")
def out_of_order_in_initialisation(model, ctx):
    i = ctx.slot
    return [("enter %d" % i, "refused"), ("setup %d 0" % i, "refused"),
            ("step %d 0 %r" % (i, model.Ts), "refused"),
            ("status %d 2 r" % i, "refused")]


@case("step")
def out_of_order_after_initialisation(model, ctx):
    i = ctx.slot
    return [("setup %d 0" % i, "refused"), ("enter %d" % i, "refused"),
            ("exit %d" % i, "refused")]


@case("end")
def out_of_order_after_terminate(model, ctx):
    i = ctx.slot
    calls = [("term %d" % i, "ok"), ("step %d %r %r" % (i, ctx.t, model.Ts), "refused"),
             ("exit %d" % i, "refused"), ("enter %d" % i, "refused")]
    calls += [("setr %d 1 %d 1" % (i, model.vr[name]), "refused") for name in model.inputs]
    return calls + [(_outputs(model, i), "ok"), ("status %d 3 b" % i, "ok")]


@case("step")
def fixed_parameter_after_initialisation(model, ctx):
    name = next(n for n in ("a0", "Ts", "seed") if n in model.vr)
    return [("setr %d 1 %d 0.5" % (ctx.slot, model.vr[name]), "refused")]


@case("step")
def output_set(model, ctx):
    return [("setr %d 1 %d 1" % (ctx.slot, model.vr[name]), "refused")
            for name in model.outputs]


@case("step")
def status_inquiries(model, ctx):
    i = ctx.slot
    return [("status %d 0 s" % i, "discard"), ("status %d 1 str" % i, "discard"),
            ("status %d 2 r" % i, "ok"), ("status %d 3 b" % i, "ok"),
            ("status %d 0 i" % i, "discard"), ("status %d 7 s" % i, "refused"),
            ("status %d -1 b" % i, "refused")]


# -- value references -------------------------------------------------------------------------

@case("step")
def value_reference_out_of_range(model, ctx):
    i = ctx.slot
    calls = []
    for vr in (999, 2147483647, 2147483648, 4294967295):
        calls += [("getr %d 1 %d" % (i, vr), "refused"), ("setr %d 1 %d 1" % (i, vr), "refused"),
                  ("geti %d 1 %d" % (i, vr), "refused"), ("seti %d 1 %d 1" % (i, vr), "refused"),
                  ("getb %d 1 %d" % (i, vr), "refused")]
    return calls


@case("step")
def value_reference_wrong_type(model, ctx):
    i = ctx.slot
    real = model.reals[0]
    return [("geti %d 1 %d" % (i, real), "refused"), ("getb %d 1 %d" % (i, real), "refused"),
            ("seti %d 1 %d 1" % (i, real), "refused")]


@case("step")
def set_real_partly_bad(model, ctx):
    if not model.inputs:
        return [("setr %d 2 %d 1 999 1" % (ctx.slot, model.reals[0]), "refused")]
    vr = model.vr[model.inputs[0]]
    return [("setr %d 2 %d 0.25 999 1" % (ctx.slot, vr), "refused"),
            ("setr %d 2 %d 0.5 %d nan" % (ctx.slot, vr, vr), "refused")]


# -- a script from a case ---------------------------------------------------------------------

def script(case_names, model, other, seed, n_calls=30):
    """The script of invalid cases: the sequence with the bad calls in instance 0, the same
    sequence without them in instance 1.

    Parameters
    ----------
    case_names : str or list of str
        Names in :data:`CASES`; each case's calls go where :data:`WHERE` says (``step``: at a
        random call of the body, drawn from ``seed``).

    Returns
    -------
    lines : list of str
    bad : dict
        Script line number -> expectation of each bad call.
    seq0, seq1 : list of int
        Script line numbers of the sequence's calls in instance 0 and in instance 1.
    """
    if isinstance(case_names, str):
        case_names = [case_names]
    order = ("instantiated", "init", "step", "end", "restart")
    case_names = sorted(case_names, key=lambda name: order.index(WHERE[name]))
    rng = random.Random(seed)
    seq = Sequence(model, rng, n_calls)
    inserted = {}
    for name in case_names:
        where = WHERE[name]
        if where == "instantiated":
            at = 0
        elif where == "init":
            at = seq.calls.index("exit {I}")
        elif where == "step":
            at = rng.randrange(seq.body, len(seq.calls) + 1)
        else:
            at = len(seq.calls)
        t, inputs = seq.context[at] if at < len(seq.calls) else (seq.t, dict(seq.inputs))
        inserted.setdefault(at, []).extend(CASES[name](model, Context(0, t, inputs, other)))

    lines = header(model, 0) + ["inst 1 0 reference 1 %s DEFAULT" % model.guid,
                                "reals 1 %d %s" % (len(model.reals),
                                                   " ".join(map(str, model.reals)))]
    lines += ["load 1 %s %s" % (word(other.dir), other.identifier),
              "inst 6 1 other 1 %s DEFAULT" % other.guid,
              "setup 6 0", "enter 6", "exit 6"]
    bad, seq0, seq1 = {}, [], []
    body = seq.lines(0)
    for k, line in enumerate(body + [None]):
        if k in inserted:
            lines.append("check on")
            for call, expect in inserted[k]:
                lines.append(call)
                bad[len(lines)] = expect
            lines.append("check off")
        if line is not None:
            lines.append(line)
            seq0.append(len(lines))
    for line in seq.lines(1):
        lines.append(line)
        seq1.append(len(lines))
    lines += ["free 0", "free 1", "free 6"]
    return lines, bad, seq0, seq1


def judge(result, bad, seq0, seq1):
    """Problems of a case's run: crash, hang, changes, non-finite values, a bad call that was
    accepted or logged nothing, and outputs of the sequence that differ from the reference's."""
    problems = result.problems()
    if result.returncode != 0 or result.timed_out:
        return problems
    statuses = result.statuses()
    logged = _logged_errors(result)
    for line, expect in bad.items():
        status = statuses.get(line)
        if status is None:
            problems.append("line %d: no status" % line)
        elif expect in ("refused", "refused_silent") and status < ERROR:
            problems.append("line %d: accepted (status %d), should be refused" % (line, status))
        elif expect == "refused" and line not in logged:
            problems.append("line %d: refused without an error message" % line)
        elif expect == "ok" and status > WARNING:
            problems.append("line %d: status %d, should be accepted" % (line, status))
        elif expect == "discard" and status != DISCARD:
            problems.append("line %d: status %d, should be fmi2Discard" % (line, status))
    for a, b in zip(seq0, seq1):
        if statuses.get(a) != statuses.get(b):
            problems.append("sequence call at line %d: status %s, without the bad calls %s"
                            % (a, statuses.get(a), statuses.get(b)))
            break
    values = result.values()
    left = [values[n] for n in seq0 if n in values]
    right = [values[n] for n in seq1 if n in values]
    if left != right:
        problems.append("the sequence's outputs differ from the run without the bad calls")
    return problems


def _logged_errors(result):
    """Script lines during whose call an error or fatal message was logged."""
    lines, pending = set(), False
    for line in result.lines:
        if line.startswith("LOG ") and line.split()[1] in ("3", "4"):
            pending = True
        elif line.startswith("S "):
            if pending:
                lines.add(int(line.split()[1]))
            pending = False
    return lines


def run_case(host, case_names, model, other, seed, **kwargs):
    """Run :func:`script` in a fresh host; ``(result, problems, lines)``."""
    lines, bad, seq0, seq1 = script(case_names, model, other, seed)
    result = run_script(host, lines, **kwargs)
    return result, judge(result, bad, seq0, seq1), lines
