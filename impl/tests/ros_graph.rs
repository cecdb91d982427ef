//! The ROS 2 face of a controller: its node shows in the ROS 2 graph (`ros_discovery_info`,
//! what `ros2 node list` reads) and its status arrives on the ROS 2 topic `/rl/status`
//! (`std_msgs/msg/String`, JSON). Real `rl controller` process, real DDS; domain 213.

mod support;

use rustdds::{
    policy::{Durability, History, Reliability},
    CDRDeserializerAdapter, DomainParticipant, QosPolicyBuilder, TopicKind,
};
use std::time::{Duration, Instant};
use support::Cluster;

const DOMAIN: u16 = 213;

#[test]
fn the_controller_is_a_ros2_node_publishing_its_status() {
    let mut cluster = Cluster::new("ros", DOMAIN, "");
    cluster.start(1);
    let participant = DomainParticipant::new(DOMAIN).unwrap();
    let qos = QosPolicyBuilder::new()
        .reliability(Reliability::Reliable {
            max_blocking_time: rustdds::Duration::ZERO,
        })
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
        .build();
    let subscriber = participant.create_subscriber(&qos).unwrap();
    let graph_topic = participant
        .create_topic(
            ros2_client::builtin_topics::ros_discovery::TOPIC_NAME.to_string(),
            ros2_client::builtin_topics::ros_discovery::TYPE_NAME.to_string(),
            &qos,
            TopicKind::NoKey,
        )
        .unwrap();
    // Every participant (this test's own ROS 2 context too) writes its entities on this
    // unkeyed topic: keep them all, not just the last one.
    let graph_qos = QosPolicyBuilder::new()
        .reliability(Reliability::Reliable {
            max_blocking_time: rustdds::Duration::ZERO,
        })
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 64 })
        .build();
    let mut graph = subscriber
        .create_datareader_no_key::<ros2_client::entities_info::ParticipantEntitiesInfo, CDRDeserializerAdapter<_>>(
            &graph_topic,
            Some(graph_qos),
        )
        .unwrap();
    // A ROS 2 node of our own subscribes to the status topic, as `ros2 topic echo` would.
    let context =
        ros2_client::Context::with_options(ros2_client::ContextOptions::new().domain_id(DOMAIN))
            .unwrap();
    let mut node = context
        .new_node(
            ros2_client::NodeName::new("/rl_test", "status_echo").unwrap(),
            ros2_client::NodeOptions::new()
                .enable_rosout(false)
                .start_parameter_services(false),
        )
        .unwrap();
    let topic = node
        .create_topic(
            &ros2_client::Name::new("/rl", "status").unwrap(),
            ros2_client::MessageTypeName::new("std_msgs", "String"),
            &ros2_client::QosProfile::default(),
        )
        .unwrap();
    let status = node
        .create_subscription::<rl_layer::wire::RosString>(&topic, None)
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut node_seen = false;
    let mut status_seen: Option<serde_json::Value> = None;
    while Instant::now() < deadline && !(node_seen && status_seen.is_some()) {
        cluster.pump(Duration::from_millis(50));
        while let Ok(Some(sample)) = graph.take_next_sample() {
            // The node list as `ros2 node list` would show it.
            let described = format!("{:?}", sample.value());
            node_seen |= described.contains("rl_controller_1");
        }
        loop {
            let message = match status.take() {
                Ok(Some((message, _info))) => message,
                Ok(None) => break,
                Err(error) => panic!("status message undecodable: {error:?}"),
            };
            if let Ok(value) = serde_json::from_str::<serde_json::Value>(&message.data) {
                if value["id"] == 1 && value["phase"] == "steady" {
                    status_seen = Some(value);
                }
            }
        }
    }
    assert!(node_seen, "node rl_controller_1 in ros_discovery_info");
    let status = status_seen.expect("a steady status of controller 1 on /rl/status");
    assert_eq!(status["role"], "primary");
    // Alone, its result is provisional (docs/protocol.md, epochs).
    assert_eq!(status["provisional"], true);
    assert_eq!(status["strength"], 15);
}
