"""The Fast DDS profile the processes start with, and when it is left out."""

import xml.etree.ElementTree as ET

from picking_common.middleware import PROFILE, use_fast_discovery

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


def test_the_profile_is_the_default_participant_announcing_every_fifth_of_a_second():
    participant = ET.parse(PROFILE).getroot().find(f'{NS}participant')
    assert participant.get('is_default_profile') == 'true'
    period = participant.find(f'{NS}rtps/{NS}builtin/{NS}discovery_config/{NS}leaseAnnouncement')
    assert int(period.find(f'{NS}sec').text) + int(period.find(f'{NS}nanosec').text) * 1e-9 == 0.2
