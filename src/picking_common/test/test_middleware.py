"""The Fast DDS profile the processes start with, and when it is left out."""

import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET

from picking_common.middleware import PROFILE, PROFILE_VARIABLES, use_fast_discovery

NS = '{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}'


def test_fast_dds_gets_the_shipped_profile_when_nothing_else_is_chosen():
    env = {}
    assert use_fast_discovery(env) and env == {'FASTRTPS_DEFAULT_PROFILES_FILE': str(PROFILE)}
    env = {'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp'}
    assert use_fast_discovery(env) and env['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(PROFILE)


def test_a_profile_of_the_users_own_or_another_middleware_is_left_alone():
    for env in ({'FASTRTPS_DEFAULT_PROFILES_FILE': '/etc/mine.xml'}, {'FASTDDS_DEFAULT_PROFILES_FILE': '/etc/mine.xml'},
                {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}):
        before = dict(env)
        assert not use_fast_discovery(env) and env == before


def test_the_profile_is_the_default_participant_announcing_every_tenth_of_a_second():
    participant = ET.parse(PROFILE).getroot().find(f'{NS}participant')
    assert participant.get('is_default_profile') == 'true'
    period = participant.find(f'{NS}rtps/{NS}builtin/{NS}discovery_config/{NS}leaseAnnouncement')
    assert int(period.find(f'{NS}sec').text) + int(period.find(f'{NS}nanosec').text) * 1e-9 == 0.1


def test_reliable_writers_heartbeat_every_tenth_of_a_second():
    writer = ET.parse(PROFILE).getroot().find(f'{NS}data_writer')
    assert writer.get('is_default_profile') == 'true'
    period = writer.find(f'{NS}times/{NS}heartbeatPeriod')
    assert int(period.find(f'{NS}sec').text) + int(period.find(f'{NS}nanosec').text) * 1e-9 == 0.1


def _fast_dds_env(profile, **more):
    """This process's environment for a Fast DDS child on loopback: with the shipped profile only, or (``profile``
    false) with none."""
    env = {**os.environ, 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp', **more}
    for v in PROFILE_VARIABLES:
        env.pop(v, None)
    if profile:
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(PROFILE)
    return env


def test_fast_dds_reads_the_profile_without_an_error():
    """Fast DDS skips what it cannot parse with only a line on stderr: a process that creates a participant and a
    writer with the profile prints none."""
    code = ('import rclpy; from std_msgs.msg import String; rclpy.init(); n = rclpy.create_node("profile_check"); '
            'n.create_publisher(String, "profile_check", 10).publish(String()); n.destroy_node(); rclpy.shutdown()')
    done = subprocess.run([sys.executable, '-c', code], env=_fast_dds_env(profile=True), capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0 and 'XMLPARSER' not in done.stderr and 'Error' not in done.stderr, done.stderr


def _shm_ports_while_talking(profile):
    """The shared-memory ports of a fresh ROS domain that two processes open while one hears the other (with
    ``profile``, or Fast DDS's defaults under the LOCALHOST discovery range)."""
    def ports(domain):
        return {f'fastrtps_port{7400 + 250 * domain + 11 + 2 * i}' for i in range(32)}
    # A domain no earlier process left a port of (a process killed leaves its ports behind).
    domain = next(d for d in range(150 + os.getpid() % 80, 232) if not ports(d) & set(os.listdir('/dev/shm')))
    user_ports = ports(domain)
    env = _fast_dds_env(profile, ROS_DOMAIN_ID=str(domain))
    talker = ('import rclpy, time; from std_msgs.msg import String; rclpy.init(); n = rclpy.create_node("talker"); '
              'p = n.create_publisher(String, "chat", 10)\nwhile True: p.publish(String(data="hi")); time.sleep(0.05)')
    listener = ('import rclpy; from std_msgs.msg import String; rclpy.init(); n = rclpy.create_node("listener"); '
                'got = []; n.create_subscription(String, "chat", got.append, 10)\n'
                'while not got: rclpy.spin_once(n, timeout_sec=0.1)\nprint("heard", flush=True)')
    opened = set()
    # (Ctrl-C as a terminal gives it, whatever the test runner ignores: the talker ends cleanly, its ports removed.)
    talking = subprocess.Popen([sys.executable, '-c', talker], env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        heard = subprocess.run([sys.executable, '-c', listener], env=env, capture_output=True, text=True,
                               timeout=60)
        opened = user_ports & set(os.listdir('/dev/shm'))
    finally:
        talking.send_signal(signal.SIGINT)
        try:
            talking.wait(10)
        except subprocess.TimeoutExpired:
            talking.kill()
            talking.wait()
    assert 'heard' in heard.stdout, heard.stderr
    return opened


def test_data_goes_over_loopback_udp_not_shared_memory():
    """Fast DDS replaces a shared-memory port whose process misses its health check (a stall of a second, a node
    killed and started again) while other writers may keep the old one: the profile keeps data off shared memory.
    Without it the same two processes talk through shared-memory ports (the check can tell)."""
    assert _shm_ports_while_talking(profile=True) == set()
    assert _shm_ports_while_talking(profile=False)
