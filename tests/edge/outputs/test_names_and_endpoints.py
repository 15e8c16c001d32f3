"""ROS 2 names and Zenoh endpoints are judged by ROS 2's and Zenoh's own rules before anything connects,
and the Zenoh writer checks every constructor argument (no zenoh session is opened by these tests)."""

from __future__ import annotations

import math

import pytest
from tactile_force.edge.errors import ArgumentTypeError, OptionsError, SceneError
from tactile_force.edge.outputs.ros2_names import ros_topic
from tactile_force.edge.outputs.zenoh_topic import (
    ZenohPublisher,
    check_endpoint,
    check_namespace,
    check_node_name,
    resolve_topic,
)


@pytest.mark.parametrize("name", ["//tactile/force", "tactile//force", "tactile/force/", "tf\t", " tf", "tf ",
                                  "tac tile", "1tactile/force", "tactile/9force", "", "/", "a/b\n", "~force"])
def test_names_ros2_refuses_are_refused_naming_the_bad_part(name):
    with pytest.raises(SceneError, match="Zenoh topic|empty"):
        resolve_topic(name, "/", "tf")


@pytest.mark.parametrize("topic, want", [("tactile/force", "/left/tactile/force"), ("/abs/force", "/abs/force"),
                                         ("~/force", "/left/tf_node/force"), ("~", "/left/tf_node"),
                                         ("~/a/b", "/left/tf_node/a/b")])
def test_relative_absolute_and_private_names_resolve_as_ros2_does(topic, want):
    assert resolve_topic(topic, "/left", "tf_node") == want


def test_a_private_name_where_no_node_expands_it_says_where_it_is_supported():
    with pytest.raises(SceneError, match="private name.*Zenoh output"):
        ros_topic("~/force", "--ros2 topic")


@pytest.mark.parametrize("node", ["tf\t", "tf node", "9lives", "", "a/b", "x" * 256, "ünï"])
def test_node_names_ros2_refuses_are_refused(node):
    with pytest.raises(SceneError, match="node name"):
        check_node_name(node)


@pytest.mark.parametrize("ns", ["//left_hand", "/left_hand/", "left", "/left hand", "/left\t", "/1left"])
def test_namespaces_ros2_refuses_are_refused(ns):
    with pytest.raises(SceneError, match="namespace"):
        check_namespace(ns)


@pytest.mark.parametrize("endpoint, said", [("tcp/127.0.0.1:99999", "outside 1..65535"), ("tcp/127.0.0.1:0", "outside"),
                                            ("tcp/127.0.0.1", "HOST:PORT"), ("foo/127.0.0.1:7447", "unknown protocol"),
                                            ("udp/host", "HOST:PORT"), (" tcp/a:1", "PROTOCOL/ADDRESS"),
                                            ("localhost:7447", "PROTOCOL/ADDRESS"), ("tcp/a:1 ", "PROTOCOL/ADDRESS")])
def test_endpoints_zenoh_cannot_connect_to_are_refused_naming_why(endpoint, said):
    with pytest.raises(SceneError, match=said):
        check_endpoint(endpoint)


@pytest.mark.parametrize("endpoint", ["tcp/localhost:7447", "tcp/10.0.0.2:7447", "tcp/[::1]:7447",
                                      "udp/192.168.1.10:7447", "tls/router.local:7447", "unixsock-stream//tmp/z.sock"])
def test_endpoints_zenoh_takes_pass(endpoint):
    assert check_endpoint(endpoint) == endpoint


@pytest.mark.parametrize("kwargs, error, said", [
    ({"connect_timeout_s": math.nan}, OptionsError, "connect_timeout_s"),
    ({"connect_timeout_s": -1}, OptionsError, "connect_timeout_s"),
    ({"connect_timeout_s": 0}, OptionsError, "connect_timeout_s"),
    ({"retry_period_s": math.nan}, OptionsError, "retry_period_s"),
    ({"retry_period_s": math.inf}, OptionsError, "retry_period_s"),
    ({"retry": "yes"}, ArgumentTypeError, "retry"),
    ({"diagnostics": "no"}, ArgumentTypeError, "diagnostics"),
    ({"interval": 1}, ArgumentTypeError, "interval"),
    ({"stamp_clock": 5}, ArgumentTypeError, "stamp_clock"),
    ({"mode": "router"}, OptionsError, "mode"),
    ({"domain_id": 233}, OptionsError, "domain_id"),
    ({"topic": 5}, ArgumentTypeError, "topic"),
    ({"endpoint": "tcp/127.0.0.1:99999"}, SceneError, "99999"),
])
def test_every_zenoh_publisher_argument_is_checked_before_anything_opens(kwargs, error, said):
    with pytest.raises(error, match=said) as info:
        ZenohPublisher(**kwargs)
    assert f"{kwargs!r}"[2:].split("'")[0] in str(info.value) or said in str(info.value)
