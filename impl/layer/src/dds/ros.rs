//! The ROS 2 face of a controller: a node on the session's participant and a status
//! publisher (`std_msgs/msg/String` on the node-relative topic `status`).

use super::{DdsError, Session};
use crate::core::types::ControllerId;
use crate::wire::RosString;
use ros2_client::{MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile};

/// Publishes status lines as `std_msgs/msg/String`.
pub struct StatusPublisher {
    publisher: Publisher<RosString>,
}

impl StatusPublisher {
    /// Publishes one status line on the node's `status` topic.
    pub fn publish(&self, status: &str) -> Result<(), DdsError> {
        self.publisher
            .publish(RosString {
                data: status.to_string(),
            })
            .map_err(|e| DdsError::Ros {
                what: "status publish",
                reason: e.to_string(),
            })
    }
}

fn ros_error(what: &'static str) -> impl Fn(String) -> DdsError {
    move |reason| DdsError::Ros { what, reason }
}

impl Session {
    /// Creates the ROS 2 node `rl_controller_<id>` in the configured namespace. It neither
    /// logs to rosout nor serves parameters: both need a spinner, which RL does not run.
    pub fn ros_node(&self, id: ControllerId) -> Result<Node, DdsError> {
        let name = NodeName::new(&self.config.ros_namespace, &format!("rl_controller_{id}"))
            .map_err(|e| ros_error("node name")(format!("{e:?}")))?;
        self.context
            .new_node(
                name,
                NodeOptions::new()
                    .enable_rosout(false)
                    .start_parameter_services(false),
            )
            .map_err(|e| ros_error("node")(format!("{e:?}")))
    }

    /// The node's status publisher: topic `status` (DDS `rt/<namespace>/status`), type
    /// `std_msgs/msg/String`, reliable keep-last (ROS defaults).
    pub fn status_publisher(&self, node: &mut Node) -> Result<StatusPublisher, DdsError> {
        let topic_name =
            Name::new("", "status").map_err(|e| ros_error("topic name")(format!("{e:?}")))?;
        let topic = node
            .create_topic(
                &topic_name,
                MessageTypeName::new("std_msgs", "String"),
                &QosProfile::default(),
            )
            .map_err(|e| ros_error("status topic")(e.to_string()))?;
        let publisher = node
            .create_publisher::<RosString>(&topic, None)
            .map_err(|e| ros_error("status publisher")(e.to_string()))?;
        Ok(StatusPublisher { publisher })
    }
}
