"""``picking-stack``: bring one arm up (simulator, state publisher, controller, planner) and take it down again.

There is no launch system here: this is the one command that starts the nodes with the shipped
parameter files, each in its own process, in one namespace. It waits until the controller holds
the arm and the planner listens, then keeps them running until Ctrl-C (or ``--for`` seconds),
stops each by its process id and reports its exit code. Each run's node logs go to a folder of
their own under ``--log-dir`` (the newest also as ``latest``; streamed with ``--show-logs``).

    picking-stack                                  # one arm in the root namespace, until Ctrl-C
    picking-stack --ns /arm2 -p picking_controller:update_rate:=250.0
    picking-stack --platform                       # every arm of picking_description/platforms/platform.yaml and picking-harvester

:class:`Stack` is the same bring-up for Python: the demo, the system tests and the benchmarks
start the arm through it.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import yaml

from picking_common.middleware import use_fast_discovery
from picking_common.startup import LAUNCHER_PID

#: The nodes in start order: their executable, ROS node name and parameter files in config/.
NODES = {
    'picking-sim': ('picking_sim', ('sim.yaml',)),
    'picking-state-publisher': ('picking_state_publisher', ()),
    'picking-controller': ('picking_controller', ('controller.yaml',)),
    'picking-planner': ('picking_planner', ('planner.yaml', 'pick_cycle.yaml')),
}
#: The nodes that name the arm's frames on /tf (each gets the stack's frame_prefix).
FRAMED = ('picking-sim', 'picking-state-publisher', 'picking-planner')
#: The nodes a user may leave out, to run a real arm's driver or robot_state_publisher in their place.
REPLACEABLE = ('picking-sim', 'picking-state-publisher')
#: Lines of a failed node's log printed with the failure.
TAIL_LINES = 12
BIN = Path(sys.executable).parent


class NodeProcess:
    """One node as a child process, its output in a log file (streamed to the terminal on request).

    Every process started is listed in ``NodeProcess.started`` with the time it stopped (None
    while it runs), so that a failing test can show the logs of those that ran during it.
    """

    started = []

    def __init__(self, name, args, log_path, echo=False):
        self.name = name
        self.log_path = Path(log_path)
        self.log = open(self.log_path, 'w')
        # A process group of its own: Ctrl-C in the terminal reaches the launcher alone, which stops the nodes one
        # after the other (stop_all); the node stops by itself if the launcher goes without stopping it.
        self.proc = subprocess.Popen([str(BIN / name), *args], stdout=subprocess.PIPE if echo else self.log,
                                     stderr=subprocess.STDOUT, env={**os.environ, LAUNCHER_PID: str(os.getpid())},
                                     text=echo or None, process_group=0)
        self._echo = None
        if echo:
            self._echo = threading.Thread(target=self._copy_output, daemon=True)
            self._echo.start()
        self.stopped_at = None
        NodeProcess.started.append(self)

    def _copy_output(self):
        for line in self.proc.stdout:
            self.log.write(line)
            self.log.flush()
            print(f'[{self.name}] {line}', end='', flush=True)

    @property
    def pid(self):
        return self.proc.pid

    def alive(self):
        return self.proc.poll() is None

    def stop(self, sig=signal.SIGINT, timeout=10.0):
        """Signal by pid and wait; returns the exit code (None if it had to be killed)."""
        return stop_all([self], sig, timeout)[0]

    def signal(self, sig):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)

    def reap(self, deadline):
        """Wait until ``deadline`` (monotonic s), then kill; the exit code, None if killed.
        A node still running is first asked for its threads' stacks (SIGUSR1: the nodes'
        faulthandler writes them to the log), so that a hang shows where it hung."""
        killed = False
        try:
            self.proc.wait(max(deadline - time.monotonic(), 0.0))
        except subprocess.TimeoutExpired:
            self.proc.send_signal(signal.SIGUSR1)
            try:
                self.proc.wait(1.0)
            except subprocess.TimeoutExpired:
                pass
            self.proc.kill()
            self.proc.wait()
            killed = True
        if self._echo is not None:
            self._echo.join(timeout=2.0)
        self.log.close()
        if self.stopped_at is None:
            self.stopped_at = time.monotonic()
        return None if killed else self.proc.returncode

    def output(self):
        if not self.log.closed:
            self.log.flush()
        return self.log_path.read_text(errors='replace')

    def tail(self, lines=TAIL_LINES):
        """The last ``lines`` lines of its log, indented, under a line naming the file."""
        last = self.output().rstrip('\n').splitlines()[-lines:]
        return '\n'.join([f'  {self.log_path}, last {len(last)} lines:', *(f'    {line}' for line in last)])


def foxglove_process(ns, port, log_dir, echo=False):
    """``picking-foxglove`` on ``port`` for the topics under ``ns`` (its own process, stopped with the stack)."""
    return NodeProcess('picking-foxglove', ['--ros-args', '-r', f'__ns:={ns}', '-p', f'port:={int(port)}'],
                       Path(log_dir) / 'picking-foxglove.log', echo=echo)


def secured_args(node_name):
    """``--enclave /<node>`` when DDS security is on (ROS_SECURITY_ENABLE): each node finds its keys by its name."""
    if os.environ.get('ROS_SECURITY_ENABLE', '').lower() == 'true':
        return ['--enclave', f'/{node_name}']
    return []


def stop_all(processes, sig=signal.SIGINT, timeout=10.0):
    """Stop ``processes`` one after the other, in the order given: signal one by pid, wait up to ``timeout`` for it
    to exit (then kill it), then the next. Returns the exit codes in order (None for a killed one).

    Not all at once: a node's DDS participant is destroyed while the others hold still. The Fast DDS of the PyPI
    wheels can hang for good destroying a participant while a discovery callback of that participant runs, and
    nodes stopping together send each other just those callbacks (docs/reliability.md)."""
    codes = []
    for p in processes:
        p.signal(sig)
        codes.append(p.reap(time.monotonic() + timeout))
    return codes


def write_stacks(processes, wait=0.5):
    """Ask every one of ``processes`` still running for its threads' stacks (SIGUSR1: a node's faulthandler writes
    them to its log and it runs on) and give them ``wait`` s to write them: what a node that went silent was
    doing."""
    running = [p for p in processes if p.alive()]
    for p in running:
        p.signal(signal.SIGUSR1)
    if running:
        time.sleep(wait)


#: s without a joint_commands message before :meth:`Stack.wait_ready` subscribes again.
RESUBSCRIBE = 10.0
_probe = []
_probe_lock = threading.Lock()


def probe_node():
    """This process's node for readiness checks, in a ROS context of its own, made once and
    shut down at exit: checks come and go without making and unmaking DDS participants."""
    with _probe_lock:
        if not _probe:
            import atexit

            import rclpy
            context = rclpy.Context()
            use_fast_discovery()
            rclpy.init(context=context)
            # A leading underscore hides it from `ros2 node list`, as the tools' own nodes are.
            node = rclpy.create_node(f'_picking_stack_{os.getpid()}', context=context)

            def close():
                node.destroy_node()
                rclpy.try_shutdown(context=context)
            atexit.register(close)
            _probe.append(node)
        return _probe[0]


class Stack:
    """Simulator, controller and planner in namespace ``ns``, each with its files from config/.

    ``args`` maps an executable (``'picking-sim'``, ...) to extra ROS arguments (``['-p',
    'update_rate:=250.0']``); ``files`` to the parameter files it gets instead of the shipped ones;
    ``without`` names nodes of :data:`REPLACEABLE` not to start (something else plays their part).
    Node logs go to ``log_dir/<ns>/<executable>.<n>.log`` (``n`` counts that node's starts).
    """

    def __init__(self, ns='/', log_dir='log/stack', args=None, files=None, config=None, echo=False, foxglove=None,
                 without=(), arm=None):
        from .shipped import config_dir
        self.ns = '/' + ns.strip('/')
        #: An arm in a namespace names its frames under it ("arm2/base_link"), as robot_state_publisher's frame_prefix.
        self.frame_prefix = self.ns.strip('/') + '/' if self.ns != '/' else ''
        self.config = Path(config) if config else config_dir()
        self.log_dir = Path(log_dir) / (self.ns.strip('/') or 'root')
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.args = {name: list((args or {}).get(name, ())) for name in NODES}
        for name in FRAMED if self.frame_prefix else ():
            self.args[name] = ['-p', f'frame_prefix:={self.frame_prefix}', *self.args[name]]
        self.files = {name: tuple((files or {}).get(name, NODES[name][1])) for name in NODES}
        if arm:
            self._use_arm(arm)
        self.echo = echo
        unknown = set(without) - set(REPLACEABLE)
        if unknown:
            raise ValueError(f'only {" and ".join(REPLACEABLE)} can be left out, not {", ".join(sorted(unknown))}')
        if 'picking-sim' not in without and not self._sim_tree():
            # A simulator with no apples leaves the gripper nothing to close on: its planner claims by the plan.
            self.args['picking-planner'] = ['-p', 'grasp_check:=false', *self.args['picking-planner']]
        self.starts = dict.fromkeys(NODES, 0)
        self.nodes = {}
        for name in NODES:
            if name not in without:
                self.start(name)
        self.foxglove = None if foxglove is None else foxglove_process(self.ns, foxglove, self.log_dir, echo)

    def _use_arm(self, arm):
        """Every node on the description's ``arm`` (``urdf/<arm>.urdf``), with ``config/arms/<arm>.yaml`` after
        its own files; ValueError naming the arms there if it has none."""
        from picking_description import urdf_path

        from .shipped import check_arm
        check_arm(self.config, arm)
        settings = Path('arms') / f'{arm}.yaml'
        urdf = urdf_path(arm)
        for name in NODES:
            self.files[name] = (*self.files[name], str(settings))
            self.args[name] = ['-p', f'urdf_path:={urdf}', *self.args[name]]

    def _sim_tree(self):
        """The simulator's ``tree`` ('' when it hangs none): its last ``tree:=`` argument, else its files'."""
        given = [a.split(':=', 1)[1] for a in self.args['picking-sim'] if a.startswith('tree:=')]
        if given:
            return given[-1].strip()
        tree = ''
        for f in self.files['picking-sim']:
            for node in (yaml.safe_load((self.config / f).read_text()) or {}).values():
                tree = str(((node or {}).get('ros__parameters') or {}).get('tree', tree) or '')
        return tree.strip()

    def start(self, name):
        """(Re)start one node; returns its :class:`NodeProcess`."""
        args = ['--ros-args', '-r', f'__ns:={self.ns}', *secured_args(NODES[name][0])]
        for f in self.files[name]:
            args += ['--params-file', str(self.config / f)]
        self.starts[name] += 1
        self.nodes[name] = NodeProcess(name, args + self.args[name],
                                       self.log_dir / f'{name}.{self.starts[name]}.log', echo=self.echo)
        return self.nodes[name]

    @property
    def sim(self):
        return self.nodes['picking-sim']

    @property
    def controller(self):
        return self.nodes['picking-controller']

    @property
    def planner(self):
        return self.nodes['picking-planner']

    @property
    def state_publisher(self):
        return self.nodes['picking-state-publisher']

    @property
    def processes(self):
        """Every process, in stop order (the reverse of the start)."""
        extra = [self.foxglove] if self.foxglove is not None else []
        return [*extra, *reversed(self.nodes.values())]

    def alive(self):
        return {p.name: p.alive() for p in self.processes}

    def wait_ready(self, timeout=60.0, stopping=None):
        """Until the controller holds the arm (joint_commands flow) and the planner listens
        (subscribes to its goal topics, serves its actions); RuntimeError if a node exits, time runs out or the
        ``stopping`` event is set (a Ctrl-C while the arm comes up).

        Asks the ROS graph and reads the newest reference through this process's probe node
        (:func:`probe_node`), so that it works whether or not the caller has initialised rclpy.
        A subscription that hears nothing for RESUBSCRIBE seconds is made again."""
        from rclpy.action.graph import get_action_names_and_types
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import JointState

        node = probe_node()
        name = f'{self.ns.rstrip("/")}/{{}}'.format
        since = time.time()
        sub, subscribed, holding = None, 0.0, False
        try:
            end = time.monotonic() + timeout
            while True:
                if sub is None or (not holding and time.monotonic() - subscribed > RESUBSCRIBE):
                    if sub is not None:
                        node.destroy_subscription(sub)
                    sub = node.create_subscription(JointState, name('joint_commands'), lambda _: None,
                                                   qos_profile_sensor_data)
                    subscribed = time.monotonic()
                while (got := sub.handle.take_message(JointState, False)) is not None:
                    stamp = got[0].header.stamp
                    holding = holding or stamp.sec + stamp.nanosec * 1e-9 > since
                listening = all(node.count_subscribers(name(t)) > 0 for t in ('goal_pose', 'goal_path', 'pick_target')) \
                    and name('pick') in dict(get_action_names_and_types(node))
                if holding and listening:
                    return
                if stopping is not None and stopping.is_set():
                    raise RuntimeError(f'stopped before the arm in {self.ns} was up')
                dead = [n for n, up in self.alive().items() if not up]
                if dead:
                    raise RuntimeError(f'{", ".join(dead)} exited while the arm was coming up '
                                       f'(see {self.log_dir})')
                if time.monotonic() > end:
                    raise RuntimeError(f'the arm in {self.ns} was not up after {timeout:g} s: '
                                       f'{"holding" if holding else "no joint_commands"}, '
                                       f'{"planner listening" if listening else "no planner listening"} '
                                       f'(see {self.log_dir})')
                time.sleep(0.05)
        finally:
            if sub is not None:
                node.destroy_subscription(sub)

    def stop(self, timeout=10.0):
        """Stop every node (SIGINT, by pid), one after the other in stop order; their exit codes by executable name."""
        procs = self.processes
        return {p.name: code for p, code in zip(procs, stop_all(procs, timeout=timeout))}


#: Several arms on one computer of 2 cores: their loops at rates that keep their deadlines together, the
#: feedback watchdog allowing for a simulator that the busy host holds up for over half a second, and
#: plans starting a second later (a long harvest plan takes seconds to reach a busy controller).
SHARED_RATES = {'picking-sim': ['-p', 'servo_rate:=250.0', '-p', 'publish_rate:=50.0'],
                'picking-controller': ['-p', 'update_rate:=100.0', '-p', 'state_timeout:=1.0'],
                'picking-planner': ['-p', 'start_delay:=1.0']}


def ros_value(v):
    """A parameter value as ``-p name:=value`` takes it (lists in YAML's flow style)."""
    if isinstance(v, (list, tuple)):
        return '[' + ','.join(ros_value(x) for x in v) + ']'
    return str(v).lower() if isinstance(v, bool) else str(v)


class PlatformStack:
    """Every arm of a platform (``picking_description/platforms/platform.yaml``, one of its layouts), each a :class:`Stack` in
    its namespace under ``ns`` with its own planner parameters, and ``picking-harvester`` in ``ns``.
    ``args`` as for :class:`Stack`, for every arm (default: :data:`SHARED_RATES` with more than one arm)."""

    def __init__(self, platform_file=None, layout=None, ns='/', log_dir='log/stack', args=None, echo=False,
                 config=None, foxglove=None):
        from scipy.spatial.transform import Rotation

        from picking_core.platform import Platform
        from picking_description import platform_path, scene_path
        self.file = Path(platform_file) if platform_file else platform_path()
        self.platform = Platform.from_yaml(self.file, layout)
        self.ns = '/' + ns.strip('/')
        if args is None:
            args = SHARED_RATES if len(self.platform.arms) > 1 else {}
        self.arms = []
        # Each arm's scene: the ground and the platform (its own fruit box is not the single arm's).
        scene = ['-p', f'scene_file:={scene_path("platform_arm")}']
        for m in self.platform.arms:
            extra = {name: list(a) for name, a in args.items()}
            extra['picking-planner'] = list(extra.get('picking-planner', [])) + scene
            extra['picking-sim'] = list(extra.get('picking-sim', [])) + scene
            for k, v in m.params.items():
                extra['picking-planner'] += ['-p', f'{k}:={ros_value(v)}']
            xyz, rpy = m.base[:3, 3], Rotation.from_matrix(m.base[:3, :3]).as_euler('xyz')
            extra['picking-state-publisher'] = list(extra.get('picking-state-publisher', [])) + [
                '-p', f'parent_frame:={self.platform.frame}', '-p', f'parent_xyz:={ros_value(xyz.tolist())}',
                '-p', f'parent_rpy:={ros_value(rpy.tolist())}']
            self.arms.append(Stack(f'{self.ns.rstrip("/")}/{m.namespace}', log_dir, args=extra, config=config,
                                   echo=echo))
        self.log_dir = Path(log_dir) / (self.ns.strip('/') or 'root')
        self.log_dir.mkdir(parents=True, exist_ok=True)
        harvester = ['--ros-args', '-r', f'__ns:={self.ns}', *secured_args('picking_harvester'),
                     '-p', f'platform_file:={self.file}']
        if layout:
            harvester += ['-p', f'layout:={layout}']
        self.harvester = NodeProcess('picking-harvester', harvester, self.log_dir / 'picking-harvester.log', echo=echo)
        self.foxglove = None if foxglove is None else foxglove_process(self.ns, foxglove, self.log_dir, echo)

    @property
    def processes(self):
        extra = [self.foxglove] if self.foxglove is not None else []
        return [*extra, self.harvester] + [p for s in self.arms for p in s.processes]

    def alive(self):
        out = {'picking-harvester': self.harvester.alive()}
        if self.foxglove is not None:
            out['picking-foxglove'] = self.foxglove.alive()
        for s in self.arms:
            out.update({f'{s.ns}/{n}': up for n, up in s.alive().items()})
        return out

    def wait_ready(self, timeout=90.0, stopping=None):
        for s in self.arms:
            s.wait_ready(timeout, stopping)
        if not self.harvester.alive():
            raise RuntimeError(f'picking-harvester exited (see {self.log_dir})')

    def stop(self, timeout=10.0):
        procs = self.processes
        return {f'{p.name} ({p.pid})': code for p, code in zip(procs, stop_all(procs, timeout=timeout))}


def overrides(items):
    """``-p node:name:=value`` items as extra ROS arguments per executable."""
    by_node = {node: exe for exe, (node, _) in NODES.items()}
    out = {}
    for item in items:
        node, sep, assignment = item.partition(':')
        if not sep or node not in by_node or ':=' not in assignment:
            raise ValueError(f'-p takes NODE:NAME:=VALUE with NODE one of {sorted(by_node)}, got {item!r}')
        out.setdefault(by_node[node], []).extend(['-p', assignment])
    return out


def run_log_dir(root):
    """A folder of its own for this run's logs under ``root`` (named by the time), linked as ``root/latest``."""
    root = Path(root)
    run = root / time.strftime('%Y-%m-%d_%H-%M-%S')
    n = 1
    while run.exists():
        n += 1
        run = root / f'{time.strftime("%Y-%m-%d_%H-%M-%S")}.{n}'
    run.mkdir(parents=True)
    latest = root / 'latest'
    try:
        if latest.is_symlink() or latest.exists():
            latest.unlink()
        latest.symlink_to(run.name)
    except OSError:
        pass                              # a file system without links: the run's folder is printed anyway
    return run


def up_line(stack, args):
    """What is up, in words: the arm or arms, the mode, where to watch them."""
    domain = os.environ.get('ROS_DOMAIN_ID', '0')
    if args.platform is not None:
        what = (f'{len(stack.arms)} arms and picking-harvester in {stack.ns} are up (domain {domain}): their '
                'controllers hold them, their planners listen')
    else:
        what = f'the arm in {stack.ns} is up (domain {domain}): the controller holds it, the planner listens'
    if args.paper:
        what += "; planning with the paper's methods (config/paper_methods.yaml)"
    if args.foxglove is not None:
        what += f'; live in Foxglove at ws://127.0.0.1:{args.foxglove}'
    return what


def build_parser():
    parser = argparse.ArgumentParser(prog='picking-stack', description=__doc__.split('\n\n')[0],
                                     epilog='Examples:\n  picking-stack\n  picking-stack --ns /arm2 --domain 7\n'
                                            '  picking-stack -p picking_controller:update_rate:=250.0 --for 10\n  picking-stack --paper',
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--ns', default='/', help='namespace of the arm (default: %(default)s)')
    parser.add_argument('--arm', help='a shipped arm other than the default picking arm: ur5e or fr3 '
                                      '(picking_description/urdf/<ARM>.urdf with config/arms/<ARM>.yaml)')
    parser.add_argument('--domain', type=int, help='ROS_DOMAIN_ID (default: the environment\'s, else 0)')
    parser.add_argument('-p', dest='params', action='append', default=[], metavar='NODE:NAME:=VALUE',
                        help='a parameter override for one node, e.g. picking_sim:noise_std:=0.001 (repeatable)')
    parser.add_argument('--log-dir', type=Path, default=Path('log/stack'),
                        help='node logs, in a folder per run (default: %(default)s/<time>, the newest as latest)')
    parser.add_argument('--show-logs', action='store_true', help='stream the node logs to this terminal too')
    parser.add_argument('--for', dest='duration', type=float, metavar='S',
                        help='stop after S seconds up (default: run until Ctrl-C)')
    parser.add_argument('--timeout', type=float, default=60.0, help='s to wait for the arm to come up')
    parser.add_argument('--platform', nargs='?', const='', metavar='FILE',
                        help='every arm of a platform (default file: picking_description/platforms/platform.yaml) in its namespace under --ns, '
                             'and picking-harvester, the coordinator of their harvest')
    parser.add_argument('--layout', help='the layout of the platform file (default: its default)')
    parser.add_argument('--foxglove', nargs='?', const=8765, type=int, metavar='PORT',
                        help='watch the arm live in Foxglove: a WebSocket server on 127.0.0.1:PORT (default 8765), '
                             'started and stopped with the stack')
    parser.add_argument('--without', action='append', default=[], choices=REPLACEABLE, metavar='EXE',
                        help='leave a node out to run something else in its place: picking-sim (a real arm\'s '
                             'driver) or picking-state-publisher (robot_state_publisher); repeatable')
    parser.add_argument('--paper', action='store_true',
                        help="the paper's interpolation methods (config/paper_methods.yaml) instead of the shipped "
                             'jerk-limited, blended ones')
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        extra = overrides(args.params)
    except ValueError as exc:
        parser.error(str(exc))
    if args.domain is not None:
        if not 0 <= args.domain <= 232:
            parser.error(f'--domain must be 0-232, got {args.domain}')
        os.environ['ROS_DOMAIN_ID'] = str(args.domain)
    # The network rule: DDS discovery stays on this machine unless the caller chose otherwise.
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    stopping = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stopping.set())
    files = {'picking-planner': NODES['picking-planner'][1] + ('paper_methods.yaml',)} if args.paper else None
    if args.platform is not None and (args.without or args.arm):
        parser.error('--without and --arm run one arm: not with --platform')
    log_dir = run_log_dir(args.log_dir)
    if args.platform is not None:
        try:
            stack = PlatformStack(args.platform or None, args.layout, args.ns, log_dir, args=extra or None,
                                  echo=args.show_logs, foxglove=args.foxglove)
        except (OSError, ValueError) as exc:
            parser.error(str(exc))
        started = {f'{p.name} ({p.log_path.parent.name})': p for p in stack.processes}
    else:
        try:
            stack = Stack(args.ns, log_dir, args=extra, files=files, echo=args.show_logs, foxglove=args.foxglove,
                          without=args.without, arm=args.arm)
        except (OSError, ValueError) as exc:
            parser.error(str(exc))
        started = stack.nodes
    for name, p in started.items():
        print(f'picking-stack: started {name} (pid {p.pid})', flush=True)
    return run(stack, args, stopping)


def run(stack, args, stopping):
    """Wait until ``stack`` is up, keep it up until ``stopping`` (or ``--for``), take it down; the exit code: 0 only
    when it came up and every node stopped with 0. A node that stopped by itself has the end of its log printed."""
    code = 0
    try:
        stack.wait_ready(args.timeout, stopping)
        print(f'picking-stack: {up_line(stack, args)}. Logs: {stack.log_dir}. Ctrl-C stops it.', flush=True)
        end = time.monotonic() + args.duration if args.duration is not None else float('inf')
        while not stopping.is_set() and time.monotonic() < end:
            dead = [n for n, up in stack.alive().items() if not up]
            if dead:
                print(f'picking-stack: {", ".join(dead)} exited; stopping the rest', file=sys.stderr)
                code = 1
                break
            # Not stopping.wait(): the signal handler's set() would wait for the lock that wait() holds in this
            # same thread, for ever.
            time.sleep(0.2)
    except RuntimeError as exc:
        print(f'picking-stack: {exc}', file=sys.stderr)
        code = 1
    finally:
        failed = [p for p in stack.processes if not p.alive()]
        codes = stack.stop()
        for p in failed:
            print(f'picking-stack: {p.name} stopped by itself with exit code {p.proc.returncode}; its log:\n'
                  f'{p.tail()}', file=sys.stderr)
        for name, c in codes.items():
            pid = f' (pid {stack.nodes[name].pid})' if name in getattr(stack, 'nodes', {}) else ''
            print(f'picking-stack: stopped {name}{pid}: exit code {c}', flush=True)
        asked = {p.name: p for p in stack.processes if p not in failed}
        for name, c in codes.items():
            if c != 0 and name in asked:
                print(f'picking-stack: {name} did not stop cleanly; its log:\n{asked[name].tail()}', file=sys.stderr)
    return code if all(c == 0 for c in codes.values()) else 1


if __name__ == '__main__':
    sys.exit(main())
