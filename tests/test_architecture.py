"""The shape of the shipped code: which package may import which, and no import cycles.

Every import counts, at module level or inside a function: a lazy import is still a
dependency of the design. Five packages, one direction: ``plan`` (the checked scenario, pure
Python) -> ``descriptions`` (world and robot descriptions, loaded into MuJoCo) -> ``nodes``
(the pure step kinds) -> ``runtime`` (what runs a step node for a transport) ->
``orchestrator`` (the run); each imports only those before it.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.helpers import ROOT

PACKAGES = ("plan", "descriptions", "nodes", "runtime", "orchestrator")
MAY_IMPORT = {pkg: set(PACKAGES[:i + 1]) for i, pkg in enumerate(PACKAGES)}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def import_graph() -> dict[str, set[str]]:
    """module -> the project modules it imports (anywhere in its code)."""
    files = project_files()
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                base = node.module
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    targets.add(full if full in files else base)
            elif isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
        graph[name] = {t for t in targets if t in files and t != name}
    return graph


def test_nothing_imports_a_package_above_it():
    wrong = sorted(f"{module} imports {target}" for module, targets in import_graph().items()
                   for target in targets
                   if target.split(".")[0] not in MAY_IMPORT[module.split(".")[0]])
    assert not wrong, "\n".join(wrong)


FORMAT_LIBRARIES = ("mujoco", "pxr")
"""The libraries that load world and robot descriptions: only descriptions/ and above."""


def external_imports(path: Path) -> set[str]:
    """The top-level names of every module ``path`` imports (anywhere in its code)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module.split(".")[0])
        elif isinstance(node, ast.Import):
            found.update(alias.name.split(".")[0] for alias in node.names)
    return found


def test_plan_is_pure_python():
    # plan/ is the checked scenario: world and robot descriptions are loaded one floor up
    wrong = sorted(f"{path.relative_to(ROOT)} imports {lib}"
                   for path in sorted((ROOT / "plan").rglob("*.py"))
                   for lib in sorted(external_imports(path) & set(FORMAT_LIBRARIES)))
    assert not wrong, "\n".join(wrong)


def test_the_purity_check_sees_lazy_imports(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("def f():\n    import mujoco\n    from pxr import Usd\n")
    assert external_imports(probe) >= {"mujoco", "pxr"}


CONVENTIONS = ("base_link", "laser", "imu", "rgbd")
"""cosim's naming conventions for a robot description, read once by the description loader
(descriptions/robot_reader.py) into the robot model the nodes are given."""
ROBOT_USERS = ("nodes/sensors", "nodes/control", "nodes/arm")


def test_nodes_find_the_robot_in_its_model_not_by_naming_convention():
    found = [f"{path.relative_to(ROOT)}:{node.lineno}: {node.value!r}"
             for folder in ROBOT_USERS for path in sorted((ROOT / folder).rglob("*.py"))
             for node in ast.walk(ast.parse(path.read_text()))
             if isinstance(node, ast.Constant) and node.value in CONVENTIONS]
    assert not found, ("take the site, camera or base from NodeConfig.robots (the robot "
                       "model), not by name:\n" + "\n".join(found))


def test_the_robot_reaches_a_node_once_as_a_typed_model():
    # NodeConfig.robots is the robot models; no parameter carries the robots' names again
    from nodes.contract import NodeConfig
    from nodes.registry import load_class
    from plan.kinds import catalogue

    assert NodeConfig.__dataclass_fields__["robots"].type == "tuple[RobotModel, ...]"
    kinds = catalogue()
    for kind, ref in sorted(kinds.kinds.items()):
        fields = getattr(load_class(ref).Params, "model_fields", {})
        assert "robots" not in fields and "robot" not in fields, kind


def string_references(files: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the project modules its string constants name ('pkg.mod' or 'pkg.mod:Class'),
    the way importlib and class references load code by name."""
    found: dict[str, set[str]] = {}
    for name, path in files.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                match = MODULE_REF.fullmatch(node.value.strip())
                if match and match.group(1) in files:
                    found.setdefault(name, set()).add(match.group(1))
    return found


MODULE_REF = re.compile(r"([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)+)(?::[A-Za-z_]\w*)?")


def project_files() -> dict[str, Path]:
    """module name -> file, for every module of the five packages."""
    return {module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def test_nothing_names_a_module_above_it_in_a_string():
    # a class loaded by name ('nodes.x:Class') is a dependency as much as an import is
    wrong = sorted(f"{module} names {target!r}"
                   for module, targets in string_references(project_files()).items()
                   for target in targets
                   if target.split(".")[0] not in MAY_IMPORT[module.split(".")[0]])
    assert not wrong, "\n".join(wrong)


def test_the_string_reference_check_sees_class_references(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text('KIND = "nodes.testing:CounterNode"\nTEXT = "nodes.a.rate=20"\n'
                     'MODULE = "orchestrator.api"\n')
    found = string_references({"plan.probe": probe, "nodes.testing": probe,
                               "orchestrator.api": probe})
    assert found["plan.probe"] == {"nodes.testing", "orchestrator.api"}


def test_the_import_graph_has_no_cycle():
    graph = import_graph()
    state: dict[str, int] = {}

    def visit(module: str, stack: list[str]) -> list[str] | None:
        state[module] = 1
        for target in sorted(graph[module]):
            if state.get(target) == 1:
                return stack[stack.index(target):] + [target]
            if target not in state and (cycle := visit(target, [*stack, target])):
                return cycle
        state[module] = 2
        return None

    for module in sorted(graph):
        if module not in state:
            cycle = visit(module, [module])
            assert cycle is None, " -> ".join(cycle)


def test_settings_do_not_travel_through_the_environment():
    # the environment carries process plumbing only (docs/how-to/development.md)
    plumbing = {"COSIM_PARENT_PID", "COSIM_ZENOH_CONNECT", "COSIM_PYTEST_TOKEN", "COSIM_GATE",
                "COSIM_RMW_GATE"}
    read = set()
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            read |= set(re.findall(r"COSIM_[A-Z_]+", path.read_text()))
    assert read <= plumbing, sorted(read - plumbing)


BLAS_CALLS = {"dot", "matmul", "einsum", "inner", "outer", "tensordot", "vdot", "linalg",
              "multi_dot", "kron"}
"""numpy functions that reach BLAS/LAPACK (or, for einsum, SIMD reductions): their last bits
depend on the kernels the CPU gets (OPENBLAS_CORETYPE). plan.rot3 is the way instead."""
PUBLISHING = ("plan", "nodes", "runtime")
"""The packages whose arithmetic ends up in published messages (the orchestrator's report
picture and outputs do not)."""


def test_no_matrix_product_on_the_way_to_published_values():
    found = []
    for pkg in PUBLISHING:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.BinOp, ast.AugAssign)) and isinstance(node.op,
                                                                               ast.MatMult):
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}: @")
                elif isinstance(node, ast.Attribute) and node.attr in BLAS_CALLS:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}: .{node.attr}")
    assert not found, ("matrix products whose bits depend on the CPU's BLAS kernels; use "
                       "plan.rot3 instead:\n" + "\n".join(found))


def test_the_floor_plan_keeps_its_limits():
    """Rooms stay small enough to read: no module of plan/ over 400 lines, at most 12
    modules at orchestrator/'s top level (the rest live in its folders)."""
    long = [f"{p.name}: {n} lines" for p in sorted((ROOT / "plan").glob("*.py"))
            if (n := len(p.read_text().splitlines())) > 400]
    assert not long, long
    top = sorted(p.name for p in (ROOT / "orchestrator").glob("*.py") if p.name != "__init__.py")
    assert len(top) <= 12, top


def test_the_run_rules_and_node_checks_are_named_checks():
    # a refusal written outside the registries would be a rule nobody can list or name
    from orchestrator import run_rules
    from runtime.node_check import NODE_CHECKS

    registered = {r.check.__name__ for r in [*run_rules.RULES, *run_rules.FOREIGN_RULES]}
    tree = ast.parse((ROOT / "orchestrator" / "run_rules.py").read_text())
    raising = {f.name for f in tree.body if isinstance(f, ast.FunctionDef)
               and any(isinstance(n, ast.Raise) for n in ast.walk(f))}
    assert raising <= registered, sorted(raising - registered)
    assert all(r.doc.strip() for r in [*run_rules.RULES, *run_rules.FOREIGN_RULES])
    assert all(c.doc for c in NODE_CHECKS)


def project_trees() -> list[tuple[Path, ast.AST]]:
    """(file, its syntax tree) for every module of the packages."""
    return [(path, ast.parse(path.read_text())) for path in project_files().values()]


OLD_FLAGS = {"in_orchestrator", "foreign", "python_program", "gated"}
"""What a node's nature was before it had one role (plan.roles): five flags, asked in 17 files."""
GATE_INSIDE = ROOT / "runtime" / "foreign_gate"
"""The Python gate runs inside a foreign program and knows no plan: its own ``gated`` list of
subscriptions is not a node's flag (nor is the kind catalogue's class reference
``kinds.foreign``)."""


def test_a_node_has_one_role_and_nothing_re_derives_it():
    from orchestrator.starters import STARTERS
    from plan.roles import NodeRole
    from plan.scenario import NodePlan

    assert not OLD_FLAGS & set(dir(NodePlan)), "NodePlan.role says what these said"
    assert set(STARTERS) == set(NodeRole), "every role has its starter"
    found = []
    for path, tree in project_trees():
        where = path.relative_to(ROOT)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr in OLD_FLAGS:
                catalogue = isinstance(node.value, ast.Name) and node.value.id == "kinds"
                if not (path.is_relative_to(GATE_INSIDE) or catalogue):
                    found.append(f"{where}:{node.lineno}: .{node.attr}")
            elif _spec_key(node, "external") and where != Path("plan/roles.py"):
                found.append(f"{where}:{node.lineno}: spec.external")
            elif (isinstance(node, ast.Compare) and _spec_key(node.left, "command")
                  and where.parts[0] != "plan"):
                found.append(f"{where}:{node.lineno}: spec.command compared")
    assert not found, "ask the node's role (NodePlan.role, plan.roles):\n" + "\n".join(found)


def _spec_key(node: ast.AST, key: str) -> bool:
    """Whether ``node`` reads ``<something>.spec.<key>``."""
    return (isinstance(node, ast.Attribute) and node.attr == key
            and isinstance(node.value, ast.Attribute) and node.value.attr == "spec")


LAYOUT_CALLERS = {"orchestrator/drivers/multi_process.py", "runtime/cosim_node.py"}
"""Where a run's process layout is decided: the orchestrator, once per run, and a node process
started from a command line (it has only the file and the options, and lays out the same)."""


def test_the_process_layout_is_decided_once_and_carried():
    import plan.packing

    assert not hasattr(plan.packing, "process_groups") and not hasattr(plan.packing,
                                                                       "subscribers")
    callers: dict[str, set[str]] = {}
    for path, tree in project_trees():
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                func = node.func
                name = func.id if isinstance(func, ast.Name) else getattr(func, "attr", None)
                if name in ("layout_of", "_group_of"):
                    callers.setdefault(name, set()).add(str(path.relative_to(ROOT)))
    assert callers["_group_of"] == {"plan/packing.py"}
    assert callers["layout_of"] == LAYOUT_CALLERS, "carry the run's ProcessLayout instead"


def test_one_reader_of_the_part_record_format():
    holders = sorted(str(p.relative_to(ROOT)) for p in project_files().values()
                     if "qHI" in p.read_text())
    assert holders == ["runtime/recording.py"], "read parts with runtime.recording"
    tail = (ROOT / "orchestrator" / "live" / "live_tail.py").read_text()
    assert "decode_records" in tail and "unpack" not in tail and "struct" not in tail


def test_the_tick_loop_imports_no_proxies():
    # the starters start the proxies, one floor up; lockstep/ drives what it is given
    wrong = sorted(f"{module} imports {target}" for module, targets in import_graph().items()
                   if module.startswith("orchestrator.lockstep")
                   for target in targets if target.startswith("orchestrator.proxies"))
    assert not wrong, "\n".join(wrong)


def test_one_quaternion_to_yaw():
    writers = sorted(str(p.relative_to(ROOT)) for p in project_files().values()
                     if re.search(r"atan2\(\s*2", p.read_text()))
    assert writers == ["plan/poses.py"], "use plan.poses.yaw"


def test_the_run_choices_are_spelled_once():
    from typing import get_type_hints

    from orchestrator.cosim_orchestrate import build_parser
    from plan.model import ScenarioModel
    from plan.options import PACKINGS, PROFILE_MODES, SPAWN_MODES, TRANSPORTS, RunOptions

    spelled = {"transport": TRANSPORTS, "spawn": SPAWN_MODES, "pack": PACKINGS,
               "profile": PROFILE_MODES}
    cli = {a.dest: a.choices for a in build_parser()._actions if a.dest in spelled}
    assert cli == spelled
    hints = get_type_hints(RunOptions)
    for field in ("spawn", "pack", "profile"):
        assert set(_literals(hints[field])) == set(spelled[field]), field
    assert set(_literals(ScenarioModel.model_fields["transport"].annotation)) == set(TRANSPORTS)


def _literals(hint) -> list[str]:
    """The string values of a Literal type hint, also inside an Optional."""
    from typing import get_args

    out = []
    for arg in get_args(hint):
        out += [arg] if isinstance(arg, str) else _literals(arg)
    return out


CONTROLLER_HOME = ("nodes/ros2_control/registry.py", "nodes/ros2_control/controllers/")
"""Where controller types are known: the registry (type name -> class) and one module per
type. Everything else asks a controller what it claims, publishes and offers."""


def controller_type_branches(files: list[tuple[str, str]]) -> list[str]:
    """Where code (``(path, source)`` pairs) outside the registry and the controllers' own
    modules names a controller type (not in a docstring), tests a controller's class
    (isinstance, issubclass, ``type(c) is X``, ``__class__.__name__ == "X"``, ``case X()``),
    or compares a controller's ``.type`` (in a module that uses nodes.ros2_control)."""
    from nodes.ros2_control.registry import CONTROLLER_TYPES

    names = set(CONTROLLER_TYPES)
    classes = {cls.__name__ for cls in CONTROLLER_TYPES.values()}
    found = []
    for where, text in files:
        if where.startswith(CONTROLLER_HOME):
            continue
        tree = ast.parse(text)
        docstrings = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr)}
        uses_control = "nodes.ros2_control" in text
        for node in ast.walk(tree):
            if (isinstance(node, ast.Constant) and node.value in names
                    and id(node) not in docstrings):
                found.append(f"{where}:{node.lineno}: {node.value!r}")
            elif (isinstance(node, ast.Call)
                  and getattr(node.func, "id", "") in ("isinstance", "issubclass")
                  and len(node.args) == 2
                  and any(getattr(a, "id", getattr(a, "attr", "")) in classes
                          for a in ast.walk(node.args[1]))):
                found.append(f"{where}:{node.lineno}: {node.func.id} of a controller class")
            elif isinstance(node, ast.MatchClass) and getattr(
                    node.cls, "id", getattr(node.cls, "attr", "")) in classes:
                found.append(f"{where}:{node.lineno}: a case of a controller class")
            elif (isinstance(node, ast.Compare) and any(
                    getattr(o, "id", getattr(o, "attr", None)) in classes
                    or (isinstance(o, ast.Constant) and o.value in classes)
                    for o in [node.left, *node.comparators])):
                found.append(f"{where}:{node.lineno}: a controller class compared")
            elif (uses_control and isinstance(node, ast.Compare)
                  and any(isinstance(o, ast.Attribute) and o.attr == "type"
                          for o in [node.left, *node.comparators])):
                found.append(f"{where}:{node.lineno}: a controller's type compared")
    return found


def test_nothing_outside_the_registry_branches_on_a_controller_type():
    files = [(str(p.relative_to(ROOT)), p.read_text()) for p in project_files().values()]
    found = controller_type_branches(files)
    assert not found, ("ask the controller (claim, publications, subscriptions, actions, "
                       "drives_base) or nodes.ros2_control.registry:\n" + "\n".join(found))


def test_the_controller_type_check_sees_a_branch():
    probe = ('"""doc: joint_state_broadcaster/JointStateBroadcaster"""\n'
             'import nodes.ros2_control\n'
             'def f(spec, ctrl):\n'
             '    if spec.type == "diff_drive_controller/DiffDriveController":\n'
             '        return isinstance(ctrl, JointTrajectoryController)\n')
    found = "\n".join(controller_type_branches([("nodes/probe.py", probe)]))
    assert "'diff_drive_controller/DiffDriveController'" in found
    assert "isinstance of a controller class" in found
    assert "a controller's type compared" in found
    others = ('def g(ctrl, cls):\n'
              '    if type(ctrl) is DiffDriveController or issubclass(cls, controllers.'
              'JointGroupPositionController):\n'
              '        return ctrl.__class__.__name__ == "JointStateBroadcaster"\n'
              '    match ctrl:\n'
              '        case ParallelGripperActionController():\n'
              '            return 1\n')
    found = controller_type_branches([("nodes/probe.py", others)])
    assert found == ["nodes/probe.py:2: a controller class compared",
                     "nodes/probe.py:2: issubclass of a controller class",
                     "nodes/probe.py:3: a controller class compared",
                     "nodes/probe.py:5: a case of a controller class"], found
    assert "JointStateBroadcaster'" not in found  # a docstring names a type; it does not branch
    assert not controller_type_branches([("nodes/ros2_control/registry.py", probe)])


NEUTRAL_DESCRIPTIONS = {
    "descriptions.robot_model",  # the robot model: plain data
    "descriptions.robot_reader",  # the model of a robot read from a compiled world, by names
    "descriptions.robot_needs",  # what a node needs of the model, worded for the user
    "descriptions.robot_state",  # TF and joint states of a described robot, from its model
    "descriptions.readers",  # the registry of description readers
    "descriptions.swarm_world", "descriptions.worldfile",  # the world, with its robots
    "descriptions.world_geometry", "descriptions.world_edits",
}
FORMAT_MODULE = re.compile(r"descriptions\.(urdf|usd|xacro|mesh)")


def format_imports(graph: dict[str, set[str]]) -> list[str]:
    """``nodes`` modules importing a descriptions module that is not format-neutral."""
    return sorted(f"{module} imports {target}" + (" (a description format's module)"
                                                   if FORMAT_MODULE.match(target) else "")
                  for module, targets in graph.items() if module.split(".")[0] == "nodes"
                  for target in targets if target.split(".")[0] == "descriptions"
                  and target not in NEUTRAL_DESCRIPTIONS)


def test_nodes_import_no_description_format_module():
    # a node sees the robot model, whatever format described the robot (issue 47 item 1):
    # formats are read behind descriptions.readers
    assert not format_imports(import_graph()), "\n".join(format_imports(import_graph()))


def test_the_format_import_check_sees_a_format_module():
    graph = {"nodes.physics.x": {"descriptions.urdf_robot", "descriptions.robot_model"},
             "descriptions.readers": {"descriptions.usd_robot"}}
    assert format_imports(graph) == [
        "nodes.physics.x imports descriptions.urdf_robot (a description format's module)"]


WORLD_MARK = ("nodes", "descriptions")  # the run's code between a description and a node
SIDE_CHANNELS = {
    # a mark written into or read out of the compiled world (a MuJoCo custom text, as the
    # described robot's 'cosim_urdf' JSON once was): a robot's facts are on its model
    "add_text": ("a MuJoCo text written into the world", WORLD_MARK),
    "mjOBJ_TEXT": ("a MuJoCo text of the compiled world", WORLD_MARK),
    "text_data": ("a MuJoCo text's data", WORLD_MARK),
    "text_adr": ("a MuJoCo text's address", WORLD_MARK),
    # the robot's description and reader settings taken from the layout by a node: its
    # model carries them (RobotModel.source, RobotModel.settings)
    "source_of": ("the robot's description from the layout", ("nodes",)),
    # a robot's base body from the layout: every robot's model is a node's
    # (NodeConfig.swarm: a lidar's other robots); the layout carries placement
    "base_of": ("the robot's base body from the layout", ("nodes",)),
}


def robot_side_channels(files: dict[str, Path], root: Path = ROOT) -> list[str]:
    """Every place that tells a node of a robot by another way than its robot model
    (``NodeConfig.robots``; a node's world check gets it too): the attributes in
    ``SIDE_CHANNELS``, in the packages each names."""
    return sorted(f"{path.relative_to(root)}:{node.lineno}: {node.attr} "
                  f"({SIDE_CHANNELS[node.attr][0]})"
                  for path in files.values()
                  for node in ast.walk(ast.parse(path.read_text()))
                  if isinstance(node, ast.Attribute) and node.attr in SIDE_CHANNELS
                  and path.relative_to(root).parts[0] in SIDE_CHANNELS[node.attr][1])


def test_the_robot_reaches_nodes_by_its_model_alone():
    # issue 47 item 1: one channel; what a node needs of the robot is on the model the plan
    # hands it (NodeConfig.robots, world_problems' ``described``)
    found = robot_side_channels(project_files())
    assert not found, "\n".join(found)


def test_the_side_channel_check_sees_a_marker_and_the_layouts_description(tmp_path):
    text = ("import mujoco\n"
            "def f(model, spec, layout, name):\n"
            "    spec.add_text(name='mark', data='{}')\n"
            "    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, 'mark')\n"
            "    return model.text_data[model.text_adr[i]], layout.source_of(name)\n"
            "def g(layout, name):\n    return layout.base_of(name)\n")
    files = {}
    for package in ("nodes", "descriptions", "plan"):
        (tmp_path / package).mkdir()
        files[package] = tmp_path / package / "probe.py"
        files[package].write_text(text)
    found = robot_side_channels(files, tmp_path)
    assert [f.split(": ")[0] + " " + f.split(": ")[1].split(" ")[0] for f in found] == [
        "descriptions/probe.py:3 add_text", "descriptions/probe.py:4 mjOBJ_TEXT",
        "descriptions/probe.py:5 text_adr", "descriptions/probe.py:5 text_data",
        "nodes/probe.py:3 add_text", "nodes/probe.py:4 mjOBJ_TEXT",
        "nodes/probe.py:5 source_of", "nodes/probe.py:5 text_adr",
        "nodes/probe.py:5 text_data", "nodes/probe.py:7 base_of"], found


DESCRIPTION_SUFFIXES = {".urdf", ".xacro", ".urdf.xacro", ".usd", ".usda", ".usdc"}
SUFFIX_CHECK_ALLOWED = {
    "descriptions/readers.py",  # the registry: where a description's format is recognised
    # SpawnEntity's object files (one-link SDFormat or URDF models of an object, told apart
    # by their root element), not robot descriptions
    "orchestrator/ros_surface/spawn_resources.py",
}


def suffix_checks(files: dict[str, Path], root: Path = ROOT) -> list[str]:
    """Every description file suffix tested outside the allowed modules (compared, in a
    table of suffixes, or given to ``endswith``): a format told by its file name where the
    registry is not asked. A suffix in a message or a file name written is no test."""
    found = []
    for path in files.values():
        where = str(path.relative_to(root))
        if where in SUFFIX_CHECK_ALLOWED:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            tested = []
            if isinstance(node, ast.Compare):
                tested = [node.left, *node.comparators]
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                    and node.func.attr == "endswith":
                tested = node.args
            elif isinstance(node, ast.Assign):
                tested = [node.value]
            for value in tested:
                items = value.elts if isinstance(value, (ast.Tuple, ast.List, ast.Set)) \
                    else [value]
                found += [f"{where}:{item.lineno} {item.value!r}" for item in items
                          if isinstance(item, ast.Constant) and isinstance(item.value, str)
                          and item.value.lower() in DESCRIPTION_SUFFIXES]
    return sorted(found)


def test_formats_are_recognised_by_the_reader_registry_only():
    wrong = suffix_checks(project_files())
    assert not wrong, "\n".join(wrong)


def test_the_suffix_check_sees_a_suffix_test(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text('S = (".usd", ".obj")\n'
                     'def f(p):\n    return p.endswith((".xacro", ".sdf")) or p.suffix == ".urdf"\n'
                     'def g(p):\n    return p.with_suffix(".usda"), f"{p}.usdc", "a .urdf"\n')
    assert suffix_checks({"probe": probe}, tmp_path) == [
        "probe.py:1 '.usd'", "probe.py:3 '.urdf'", "probe.py:3 '.xacro'"]


def test_no_scenario_remaps_a_cosim_topic():
    """cosim wires physics to a controller manager itself (issue 48): no scenario names
    one of cosim's own topics in a remap."""
    import yaml

    found = []
    for path in sorted((ROOT / "scenarios").glob("*.yaml")):
        for node in yaml.safe_load(path.read_text()).get("nodes", []):
            for own, graph in (node.get("remap") or {}).items():
                if own.startswith("/cosim/") or graph.startswith("/cosim/"):
                    found.append(f"{path.name}: {node['name']}: {own} -> {graph}")
    assert not found, "cosim wires its own topics (plan/hardware_wiring.py):\n" + "\n".join(found)


TF_NAME_READERS = {"description_names", "frame_problems", "robot_params"}
"""Where nodes/ may read the physics node's ``tf.sites`` and ``tf.cameras``: naming what an
MJCF robot's model is read by, and the world check of those names. The frames themselves
come off the robot model (``RobotModel.site_frames``, ``camera_frames``)."""


def tf_name_reads(files: dict[str, Path], root: Path = ROOT) -> list[str]:
    """Every read of a ``sites`` or ``cameras`` attribute in nodes/ outside the functions
    ``TF_NAME_READERS`` allows."""
    found: list[str] = []

    def visit(node: ast.AST, path: Path, allowed: bool) -> None:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            allowed = allowed or node.name in TF_NAME_READERS
        if (isinstance(node, ast.Attribute) and node.attr in ("sites", "cameras")
                and not allowed):
            found.append(f"{path.relative_to(root)}:{node.lineno}: {node.attr}")
        for child in ast.iter_child_nodes(node):
            visit(child, path, allowed)
    for path in files.values():
        if path.relative_to(root).parts[0] == "nodes":
            visit(ast.parse(path.read_text()), path, False)
    return sorted(found)


def test_every_robots_frames_come_off_its_model():
    # issue 47 item 1: an MJCF robot's TF sites and cameras are on its model as a described
    # robot's links are; the physics node's tf parameters only name them for its reader
    found = tf_name_reads(project_files())
    assert not found, "\n".join(found)


def test_the_tf_name_check_sees_a_read(tmp_path):
    (tmp_path / "nodes").mkdir()
    probe = tmp_path / "nodes" / "probe.py"
    probe.write_text("def frames(params):\n    return params.tf.sites, params.tf.cameras\n\n"
                     "def description_names(params):\n    return params.tf.sites\n")
    assert tf_name_reads({"nodes.probe": probe}, tmp_path) == [
        "nodes/probe.py:2: cameras", "nodes/probe.py:2: sites"]
