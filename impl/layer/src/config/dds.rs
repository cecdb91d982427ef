//! The `[dds]` section: the DDS domain, the topic names and the ROS 2 namespace.

use super::error::{check, quoted, InvalidValue};
use serde::{Deserialize, Serialize};

/// DDS domain and topic names. The camera's two topics default to the original application's
/// names and types (wire-compatible with PixyShapes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Dds {
    /// RL's DDS domain id (the demo's: 53); at most [`DOMAIN_MAX`]. The network monitor uses
    /// the next two.
    pub domain: u16,
    /// The controller heartbeat (RLCHB), published every heartbeat period.
    pub heartbeat_topic: String,
    /// The durable vote records, one per controller.
    pub vote_topic: String,
    /// Controller alarms: a peer lost or FAILED, raised and cleared.
    pub controller_alarm_topic: String,
    /// Network alarms the network monitor raises and clears.
    pub network_alarm_topic: String,
    /// The network heartbeat (RLNHB), on the network monitor's own domains.
    pub network_heartbeat_topic: String,
    /// The actuator's commands (ServoControl), shared with PixyShapes; exclusive ownership by
    /// role strength.
    pub command_topic: String,
    /// The voted command topic: every controller with a role publishes its own instance of
    /// each command (keyed by its id, shared ownership, tagged with the input it answers) for a
    /// receiver that votes on them (crate::vote_reader), beside the exclusive `command_topic`.
    /// Empty (the default): `command_topic` with `_voted` appended
    /// ([`Dds::voted_topic_name`]), so a group that names its own command topic has its own
    /// voted topic too. Like the command topic it is the application's: a group does not rename
    /// it.
    pub voted_command_topic: String,
    /// The camera's circles the tracker reads, shared with PixyShapes.
    pub camera_topic: String,
    /// ROS 2 node namespace; each controller's node is `rl_controller_<id>` in it.
    pub ros_namespace: String,
    /// The redundancy group these controllers form ("": the one group of the domain). Groups
    /// on one domain and one LAN do not hear each other: RL's topics and the ROS 2 namespace
    /// carry the name ([`Dds::grouped`]), so ids are per group. The command, voted command and
    /// camera topics are the application's and keep their names.
    pub group: String,
}

impl Default for Dds {
    fn default() -> Dds {
        Dds {
            domain: 53,
            heartbeat_topic: "rl/controller_heartbeat".into(),
            vote_topic: "rl/vote".into(),
            controller_alarm_topic: "rl/controller_alarm".into(),
            network_alarm_topic: "rl/network_alarm".into(),
            network_heartbeat_topic: "rl/network_heartbeat".into(),
            command_topic: "pixy/servo_control".into(),
            voted_command_topic: String::new(),
            camera_topic: "Circle".into(),
            ros_namespace: "/rl".into(),
            group: String::new(),
        }
    }
}

/// The highest DDS domain id whose RTPS ports fit in 16 bits: the well-known ports are
/// `7400 + 250 * domain + offset`, and domain 233 already passes 65535.
pub const DOMAIN_MAX: u16 = 232;

impl Dds {
    /// The names this group's participants use: RL's five topics with the group after their
    /// first path segment (`rl/controller_heartbeat` becomes `rl/nav/controller_heartbeat` in
    /// group `nav`) and the ROS 2 namespace with the group appended (`/rl/nav`); the same
    /// names without a group.
    pub fn grouped(&self) -> Dds {
        if self.group.is_empty() {
            return self.clone();
        }
        let topic = |base: &str| match base.split_once('/') {
            Some((first, rest)) => format!("{first}/{}/{rest}", self.group),
            None => format!("{}/{base}", self.group),
        };
        let ros_namespace = match self.ros_namespace.as_str() {
            "/" => format!("/{}", self.group),
            namespace => format!("{namespace}/{}", self.group),
        };
        Dds {
            heartbeat_topic: topic(&self.heartbeat_topic),
            vote_topic: topic(&self.vote_topic),
            controller_alarm_topic: topic(&self.controller_alarm_topic),
            network_alarm_topic: topic(&self.network_alarm_topic),
            network_heartbeat_topic: topic(&self.network_heartbeat_topic),
            ros_namespace,
            ..self.clone()
        }
    }

    /// This configuration with group `group` ([`Dds::grouped`] of it): the names another
    /// group on the same domain uses, for a view of every group or an application that follows
    /// another group's owner. `self` is the configuration as written (not already grouped).
    pub fn of_group(&self, group: &str) -> Dds {
        Dds {
            group: group.to_string(),
            ..self.clone()
        }
        .grouped()
    }

    /// The group whose heartbeat topic is `topic` under this configuration's names (as written,
    /// not already grouped): `""` for the name as configured, `nav` for the name
    /// [`Dds::grouped`] gives group `nav`; `None` for any other topic (or a group name that
    /// `dds.group` would refuse).
    pub fn group_of_heartbeat_topic(&self, topic: &str) -> Option<String> {
        if topic == self.heartbeat_topic {
            return Some(String::new());
        }
        let (prefix, suffix) = match self.heartbeat_topic.split_once('/') {
            Some((first, rest)) => (format!("{first}/"), format!("/{rest}")),
            None => (String::new(), format!("/{}", self.heartbeat_topic)),
        };
        let group = topic.strip_prefix(&prefix)?.strip_suffix(&suffix)?;
        let valid = is_group_name(group) && self.of_group(group).heartbeat_topic == topic;
        valid.then(|| group.to_string())
    }

    /// The voted command topic's name: `voted_command_topic`, or when it is empty
    /// `command_topic` with `_voted` appended (`pixy/servo_control_voted` by default).
    pub fn voted_topic_name(&self) -> String {
        if self.voted_command_topic.is_empty() {
            format!("{}_voted", self.command_topic)
        } else {
            self.voted_command_topic.clone()
        }
    }

    /// The topic fields with their dotted paths, in file order (the voted command topic by
    /// the name it takes, [`Dds::voted_topic_name`]).
    fn topics(&self) -> [(&'static str, String); 8] {
        [
            ("dds.heartbeat_topic", self.heartbeat_topic.clone()),
            ("dds.vote_topic", self.vote_topic.clone()),
            (
                "dds.controller_alarm_topic",
                self.controller_alarm_topic.clone(),
            ),
            ("dds.network_alarm_topic", self.network_alarm_topic.clone()),
            (
                "dds.network_heartbeat_topic",
                self.network_heartbeat_topic.clone(),
            ),
            ("dds.command_topic", self.command_topic.clone()),
            ("dds.voted_command_topic", self.voted_topic_name()),
            ("dds.camera_topic", self.camera_topic.clone()),
        ]
    }

    /// Checks the domain, that every topic name is non-empty, without whitespace and distinct,
    /// and the ROS 2 namespace.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        check(self.domain <= DOMAIN_MAX, "dds.domain", self.domain, || {
            format!("must be at most {DOMAIN_MAX} (higher domains' RTPS ports pass 65535)")
        })?;
        let topics = self.topics();
        for (field, name) in &topics {
            check(
                !name.is_empty() && !name.chars().any(char::is_whitespace),
                field,
                quoted(name),
                || "must be a non-empty topic name without whitespace".to_string(),
            )?;
        }
        // Two kinds of sample on one topic name would not match in DDS.
        for (index, (field, name)) in topics.iter().enumerate() {
            if let Some((other_field, _)) = topics[..index].iter().find(|(_, other)| other == name)
            {
                return Err(InvalidValue::new(
                    field,
                    quoted(name),
                    format!("must differ from {other_field}"),
                ));
            }
        }
        check(
            self.group.is_empty() || is_group_name(&self.group),
            "dds.group",
            quoted(&self.group),
            || {
                "must be empty (one group on the domain) or 1..=32 letters, digits and `_`, \
                 not starting with a digit"
                    .to_string()
            },
        )?;
        check(
            is_ros_namespace(&self.ros_namespace),
            "dds.ros_namespace",
            quoted(&self.ros_namespace),
            || {
                "must be an absolute ROS 2 namespace: `/` or `/`-separated names of letters, \
                 digits and `_`, each not starting with a digit"
                    .to_string()
            },
        )
    }
}

/// ROS 2's rule for a fully qualified namespace (`/`, `/rl`, `/robots/rl_1`).
fn is_ros_namespace(namespace: &str) -> bool {
    let Some(rest) = namespace.strip_prefix('/') else {
        return false;
    };
    rest.is_empty() || rest.split('/').all(is_ros_name)
}

/// A non-empty `dds.group`: one ROS 2 name token of at most 32 characters (it becomes a topic
/// path segment and a ROS 2 namespace segment).
fn is_group_name(group: &str) -> bool {
    is_ros_name(group) && group.len() <= 32
}

/// One ROS 2 name token: letters, digits and `_`, not starting with a digit.
fn is_ros_name(token: &str) -> bool {
    token
        .chars()
        .next()
        .is_some_and(|first| first.is_ascii_alphabetic() || first == '_')
        && token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}
