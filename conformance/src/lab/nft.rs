//! nftables rule sets for the network faults, as text (pure, so tests read them). Each fault
//! gets its own table (`inet labfN`) in the namespaces it touches, so faults overlap freely and
//! healing one deletes exactly its table. Rules that name nodes name them by their addresses
//! on both nets: RL's traffic uses both, so a split that left one net whole would split
//! nothing.

use super::lan::{Net, Node, MULTICAST};

/// What one namespace drops for a fault: rules for its input and output hooks.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Rules {
    pub input: Vec<String>,
    pub output: Vec<String>,
}

impl Rules {
    /// Drops every packet from and to `peers` (a side of a partition, a cut).
    pub fn isolate_from(peers: &[Node]) -> Rules {
        let set = addr_set(peers);
        Rules {
            input: vec![format!("ip saddr {set} drop")],
            output: vec![format!("ip daddr {set} drop")],
        }
    }

    /// Drops arriving packets from `senders` only (one-way loss at the receiver).
    pub fn deaf_to(senders: &[Node]) -> Rules {
        Rules {
            input: vec![format!("ip saddr {} drop", addr_set(senders))],
            output: Vec::new(),
        }
    }

    /// Drops `percent` % of UDP packets at random, both ways.
    pub fn random_loss(percent: u8) -> Rules {
        let rule = format!("meta l4proto udp numgen random mod 100 < {percent} drop");
        Rules {
            input: vec![rule.clone()],
            output: vec![rule],
        }
    }

    /// Drops everything in and out of the namespace's interface into `net`: that node's link
    /// into the net is dead, its link into the other one whole. Counted, so `nft list ruleset`
    /// in the namespace shows what the dead link swallowed.
    pub fn link_down(net: Net) -> Rules {
        let inside = net.inside();
        Rules {
            input: vec![format!("iifname \"{inside}\" counter drop")],
            output: vec![format!("oifname \"{inside}\" counter drop")],
        }
    }

    /// Drops multicast both ways (DDS discovery and anything sent to a group).
    pub fn no_multicast() -> Rules {
        let rule = format!("ip daddr {MULTICAST} drop");
        Rules {
            input: vec![rule.clone()],
            output: vec![rule],
        }
    }

    /// The script that creates table `table` with these rules.
    pub fn script(&self, table: &str) -> String {
        let chain = |name: &str, rules: &[String]| {
            let body: String = rules.iter().map(|r| format!("    {r}\n")).collect();
            format!(
                "  chain {name} {{\n    type filter hook {name} priority 0; policy accept;\n{body}  }}\n"
            )
        };
        format!(
            "table inet {table} {{\n{}{}}}\n",
            chain("input", &self.input),
            chain("output", &self.output)
        )
    }
}

/// The script that removes table `table`.
pub fn delete_script(table: &str) -> String {
    format!("delete table inet {table}\n")
}

/// `{ 10.201.1.2, 10.202.1.2, 10.201.1.3, 10.202.1.3 }`: the nodes on both nets.
fn addr_set(nodes: &[Node]) -> String {
    let addrs: Vec<String> = nodes.iter().flat_map(|n| n.addrs()).collect();
    format!("{{ {} }}", addrs.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cut_drops_both_ways_by_address() {
        let script =
            Rules::isolate_from(&[Node::Controller(2), Node::Controller(3)]).script("labf1");
        assert!(script.starts_with("table inet labf1 {"));
        let both_nets = "{ 10.201.1.2, 10.202.1.2, 10.201.1.3, 10.202.1.3 }";
        assert!(script.contains(&format!("ip saddr {both_nets} drop")));
        assert!(script.contains(&format!("ip daddr {both_nets} drop")));
        assert!(script.contains("type filter hook input priority 0; policy accept;"));
    }

    #[test]
    fn a_link_down_drops_everything_on_one_interface_both_ways() {
        let rules = Rules::link_down(Net::B);
        assert_eq!(rules.input, ["iifname \"b0\" counter drop"]);
        assert_eq!(rules.output, ["oifname \"b0\" counter drop"]);
    }

    #[test]
    fn loss_is_random_per_packet_on_udp() {
        let rules = Rules::random_loss(20);
        assert_eq!(
            rules.input,
            ["meta l4proto udp numgen random mod 100 < 20 drop"]
        );
        assert_eq!(rules.input, rules.output);
    }
}
