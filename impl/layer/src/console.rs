//! The controller's console line (paper, "LED Operation": "corresponding messages will be
//! printed on the controller console indicating each controller's Relative Number, and who is
//! primary"): a pure function of the core's [`Status`].

use crate::core::{Phase, Role, Status};

/// This controller's relative number (its role) and the Primary, on one line.
pub fn console_line(status: &Status) -> String {
    let report = &status.report;
    let role = match (report.phase, report.role) {
        (Phase::Failed, _) => "FAILED".to_string(),
        (_, Some(role)) => format!("{role} ({})", report.strength.unwrap_or_default()),
        (Phase::Steady, None) => "spare (no role)".to_string(),
        (_, None) => "no role yet".to_string(),
    };
    let primary = report
        .agreed
        .and_then(|a| a.holder(Role::Primary))
        .map(|id| format!("C{id}"))
        .unwrap_or_else(|| "none".to_string());
    let agreed = report
        .agreed
        .map(|a| a.to_string())
        .unwrap_or_else(|| "-".to_string());
    format!(
        "C{} {:<12} {:<16} Primary: {:<4} agreed [{}]",
        report.id,
        report.phase.name(),
        role,
        primary,
        agreed
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::{Assignment, Holder, Strength};

    #[test]
    fn the_line_names_the_role_with_its_strength_and_the_primary() {
        let mut status = Status::initial(2, 5);
        assert_eq!(
            console_line(&status),
            "C2 initializing no role yet      Primary: none agreed [-]"
        );
        let agreed = Assignment::from_ranked([1, 2, 3].map(|id| Holder { id, incarnation: 0 }));
        status.report.phase = Phase::Steady;
        status.report.role = Some(Role::Secondary);
        status.report.strength = Some(Strength(20));
        status.report.agreed = Some(agreed);
        assert_eq!(
            console_line(&status),
            "C2 steady       secondary (20)   Primary: C1   agreed [P=1 S=2 T=3]"
        );
        status.report.phase = Phase::Failed;
        assert!(console_line(&status).starts_with("C2 failed       FAILED "));
    }
}
