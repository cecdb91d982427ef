//! A trace's cuts and pulled cables on the virtual LAN (`crate::lab::lan`), with the lab's
//! own rules: `Isolate` is the lab's cut (`crate::lab::faults::cut_rules`: nftables at the
//! controller and at each peer, the actuator still hears it), `Unplug` the lab's pulled
//! cables (`crate::lab::faults::unplug`: its links down, carrier and all), and `Heal` undoes
//! whichever the controller has.
//!
//! A cut's tables go into three namespaces at once, one thread each: one `ip netns exec nft`
//! takes some milliseconds, and the whole cut must be in force before the round's heartbeats
//! go out, a quarter period after the boundary (the driver checks that it was).

use crate::lab::faults::{cut_rules, unplug};
use crate::lab::host;
use crate::lab::lan::Lan;
use crate::lab::nft;
use model::Action;
use std::collections::BTreeMap;

/// What one controller's cut or pulled cables did, to undo.
#[derive(Debug)]
enum InForce {
    /// nftables tables, `(namespace, table)`.
    Tables(Vec<(String, String)>),
    /// Host ends of its links, taken down.
    LinksDown(Vec<String>),
}

/// The cuts and pulled cables in force, by controller.
pub struct Cuts<'a> {
    lan: &'a Lan,
    in_force: BTreeMap<u8, InForce>,
}

impl<'a> Cuts<'a> {
    pub fn new(lan: &'a Lan) -> Cuts<'a> {
        Cuts {
            lan,
            in_force: BTreeMap::new(),
        }
    }

    /// Applies `Isolate`, `Unplug` or `Heal`; any other action is no cut. An error says what
    /// failed.
    pub fn apply(&mut self, action: Action) -> Result<(), String> {
        match action {
            Action::Isolate { controller } => {
                self.heal(controller)?;
                let table = table_name(controller);
                let rules: Vec<(String, String)> = cut_rules(controller)
                    .into_iter()
                    .map(|(node, rules)| (self.lan.ns(node), rules.script(&table)))
                    .collect();
                run_at_once(&rules)?;
                let tables = rules.into_iter().map(|(ns, _)| (ns, table.clone()));
                self.in_force
                    .insert(controller, InForce::Tables(tables.collect()));
                Ok(())
            }
            Action::Unplug { controller } => {
                self.heal(controller)?;
                let links = unplug(self.lan, controller).map_err(|e| e.to_string())?;
                self.in_force.insert(controller, InForce::LinksDown(links));
                Ok(())
            }
            Action::Heal { controller } => self.heal(controller),
            _ => Ok(()),
        }
    }

    /// Undoes controller `id`'s cut or pulled cables, if it has one.
    fn heal(&mut self, id: u8) -> Result<(), String> {
        match self.in_force.remove(&id) {
            Some(InForce::Tables(tables)) => {
                let scripts: Vec<(String, String)> = tables
                    .into_iter()
                    .map(|(ns, table)| (ns, nft::delete_script(&table)))
                    .collect();
                run_at_once(&scripts)
            }
            Some(InForce::LinksDown(links)) => {
                for link in links {
                    host::run("ip", &["link", "set", &link, "up"]).map_err(|e| e.to_string())?;
                }
                Ok(())
            }
            None => Ok(()),
        }
    }

    /// Heals everything (between attempts); errors are ignored, the LAN goes at the end.
    pub fn heal_all(&mut self) {
        let ids: Vec<u8> = self.in_force.keys().copied().collect();
        for id in ids {
            let _ = self.heal(id);
        }
    }
}

/// The nftables table of controller `id`'s cut.
fn table_name(id: u8) -> String {
    format!("rlcut{id}")
}

/// Runs each `(namespace, nft script)` at the same time; the first error, if any.
fn run_at_once(scripts: &[(String, String)]) -> Result<(), String> {
    std::thread::scope(|scope| {
        let runs: Vec<_> = scripts
            .iter()
            .map(|(ns, script)| scope.spawn(move || host::nft(ns, script)))
            .collect();
        let mut first_error = None;
        for run in runs {
            let result = run
                .join()
                .map_err(|_| "an nft thread panicked".to_string())
                .and_then(|r| r.map_err(|e| e.to_string()));
            if let Err(error) = result {
                first_error.get_or_insert(error);
            }
        }
        first_error.map_or(Ok(()), Err)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lab::lan::Node;

    #[test]
    fn a_cut_touches_the_controller_and_both_peers_but_not_the_actuator() {
        let nodes: Vec<Node> = cut_rules(2).into_iter().map(|(node, _)| node).collect();
        assert_eq!(
            nodes,
            [
                Node::Controller(2),
                Node::Controller(1),
                Node::Controller(3)
            ]
        );
        assert_eq!(table_name(2), "rlcut2");
    }
}
