//! The DDS Security XML documents RL signs: the domain governance (how each topic is
//! protected) and a participant's permissions (what it may publish and read).
//!
//! RL's own topics (heartbeat, vote, controller alarm, network alarm) are access-controlled
//! and signed: only a participant with a certificate from the RL CA and permissions signed by
//! it can read or write them, and every submessage (a DATA with its payload, a HEARTBEAT, an
//! ACKNACK) carries a message authentication code (`metadata_protection_kind` SIGN), so a
//! forged or altered sample is dropped. The payload is not protected separately
//! (`data_protection_kind` NONE): RustDDS 0.15.1 fails to decode every sample whose payload
//! is signed or encrypted (ring "Unspecified"; measured: no formation), and the submessage's
//! MAC covers the payload anyway. The device topics (command, voted command, camera) are the
//! same; left open for devices without DDS Security (`open_device_topics`), they are not on
//! the secured participant at all but on a second, unsecured one (crate::dds::Session):
//! RustDDS 0.15.1 sends protected submessages to unauthenticated participants even for
//! unprotected topics (measured: an unsecured servo received no command). Any other topic (the ROS 2 graph:
//! `rt/rosout`, `ros_discovery_info`) is unprotected.

use crate::config::{Dds, DOMAIN_MAX};

/// Whose permissions: a controller may publish RL's topics; an application (`rl status`,
/// `rl servo`, `rl shapes`, a camera) may read them and publish only the camera topic.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Grantee {
    /// A controller, by its id (1..=250).
    Controller(u8),
    /// An application, by its name (1..=64 letters, digits, `-` or `_`).
    Application(String),
}

impl Grantee {
    /// The certificate's subject common name (the permissions grant names it too).
    pub fn common_name(&self) -> String {
        match self {
            Grantee::Controller(id) => format!("rl-controller-{id}"),
            Grantee::Application(name) => format!("rl-app-{name}"),
        }
    }

    /// The subject as DDS Security writes it (RFC 4514).
    pub fn subject_name(&self) -> String {
        format!("CN={}", self.common_name())
    }

    /// The keystore directory's name under `rl keys --dir`.
    pub fn directory_name(&self) -> String {
        match self {
            Grantee::Controller(id) => format!("c{id}"),
            Grantee::Application(name) => name.clone(),
        }
    }
}

/// RL's own topics: only controllers publish them.
fn controller_topics(dds: &Dds) -> [&str; 4] {
    [
        &dds.heartbeat_topic,
        &dds.vote_topic,
        &dds.controller_alarm_topic,
        &dds.network_alarm_topic,
    ]
}

/// The ROS 2 graph topics every participant's node uses (unprotected in the governance).
const ROS_TOPICS: [&str; 4] = ["rt/*", "rq/*", "rr/*", "ros_discovery_info"];

fn protected_rule(topic: &str) -> String {
    format!(
        "      <topic_rule>
        <topic_expression>{topic}</topic_expression>
        <enable_discovery_protection>true</enable_discovery_protection>
        <enable_liveliness_protection>false</enable_liveliness_protection>
        <enable_read_access_control>true</enable_read_access_control>
        <enable_write_access_control>true</enable_write_access_control>
        <metadata_protection_kind>SIGN</metadata_protection_kind>
        <data_protection_kind>NONE</data_protection_kind>
      </topic_rule>\n"
    )
}

fn open_rule(topic: &str) -> String {
    format!(
        "      <topic_rule>
        <topic_expression>{topic}</topic_expression>
        <enable_discovery_protection>false</enable_discovery_protection>
        <enable_liveliness_protection>false</enable_liveliness_protection>
        <enable_read_access_control>false</enable_read_access_control>
        <enable_write_access_control>false</enable_write_access_control>
        <metadata_protection_kind>NONE</metadata_protection_kind>
        <data_protection_kind>NONE</data_protection_kind>
      </topic_rule>\n"
    )
}

/// The governance document.
pub fn governance(dds: &Dds) -> String {
    // RL's topics as the configured group names them.
    let dds = &dds.grouped();
    let mut rules = String::new();
    for topic in controller_topics(dds) {
        rules.push_str(&protected_rule(topic));
    }
    let voted = dds.voted_topic_name();
    for topic in [&dds.command_topic, &voted, &dds.camera_topic] {
        rules.push_str(&protected_rule(topic));
    }
    // The first matching rule applies: everything else (the ROS 2 graph) is open.
    rules.push_str(&open_rule("*"));
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains>
        <id_range><min>0</min><max>{DOMAIN_MAX}</max></id_range>
      </domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>SIGN</discovery_protection_kind>
      <liveliness_protection_kind>SIGN</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
{rules}      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
"#
    )
}

fn topic_list(topics: &[&str]) -> String {
    topics
        .iter()
        .map(|t| format!("            <topic>{t}</topic>\n"))
        .collect()
}

/// The permissions document for `grantee`, valid from `not_before` to `not_after`
/// (`YYYY-MM-DDTHH:MM:SS`, UTC: the certificate's validity).
pub fn permissions(dds: &Dds, grantee: &Grantee, not_before: &str, not_after: &str) -> String {
    let dds = &dds.grouped();
    let voted = dds.voted_topic_name();
    let mut publish: Vec<&str> = ROS_TOPICS.to_vec();
    match grantee {
        Grantee::Controller(_) => {
            publish.extend(controller_topics(dds));
            publish.push(&dds.command_topic);
            publish.push(&voted);
        }
        Grantee::Application(_) => publish.push(&dds.camera_topic),
    }
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-Security/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="{name}">
      <subject_name>{subject}</subject_name>
      <validity>
        <not_before>{not_before}</not_before>
        <not_after>{not_after}</not_after>
      </validity>
      <allow_rule>
        <domains>
          <id_range><min>0</min><max>{DOMAIN_MAX}</max></id_range>
        </domains>
        <publish>
          <topics>
{publish}          </topics>
        </publish>
        <subscribe>
          <topics>
            <topic>*</topic>
          </topics>
        </subscribe>
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
"#,
        name = grantee.common_name(),
        subject = grantee.subject_name(),
        publish = topic_list(&publish),
    )
}

/// The `<subject_name>` of a permissions document, to check it against the certificate.
pub fn permissions_subject(document: &str) -> Option<&str> {
    let (_, rest) = document.split_once("<subject_name>")?;
    rest.split_once("</subject_name>")
        .map(|(subject, _)| subject.trim())
}
