//! `rl keys`: make the CA and the participants' keystores (docs/security.md).

use clap::{Args, Subcommand};
use std::path::PathBuf;

/// Make DDS Security keystores: `init` once (the CA), `add` per controller or application.
#[derive(Args, Debug)]
pub struct KeysArgs {
    #[command(subcommand)]
    pub action: KeysAction,
}

#[derive(Subcommand, Debug)]
pub enum KeysAction {
    /// A new CA (ca.key.pem, ca.cert.pem) and the governance document in DIR.
    ///
    /// Example: rl keys init --dir keys
    Init {
        /// The directory (created if missing). Keep it, with the CA's key, on the build
        /// machine.
        #[arg(long, value_name = "DIR")]
        dir: PathBuf,
        #[command(flatten)]
        common: Common,
    },
    /// One participant's keystore in DIR/cID (a controller: DIR/c1 for --id 1) or DIR/NAME
    /// (an application: rl status, rl servo, rl shapes, a camera); copy that directory to
    /// the machine and name it as the keystore of rl.toml's security section.
    ///
    /// Example: rl keys add --dir keys --id 1
    Add {
        /// The directory `rl keys init` made.
        #[arg(long, value_name = "DIR")]
        dir: PathBuf,
        /// A controller's id: it may publish RL's topics and the command topic.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=250), conflicts_with = "app", required_unless_present = "app")]
        id: Option<u8>,
        /// An application's name (letters, digits, '-', '_'): it may read RL's topics and
        /// publish only the camera topic.
        #[arg(long, value_name = "NAME")]
        app: Option<String>,
        #[command(flatten)]
        common: Common,
    },
}

#[derive(Args, Debug)]
pub struct Common {
    /// The configuration whose topic names the documents use (default: the defaults).
    #[arg(long, value_name = "PATH")]
    pub config: Option<PathBuf>,
    /// How long the certificates are valid, in days from --not-before.
    #[arg(long, value_name = "DAYS", default_value_t = 3650)]
    pub days: u32,
    /// Start of validity, YYYY-MM-DD (UTC midnight; default: now).
    #[arg(long, value_name = "DATE")]
    pub not_before: Option<String>,
}

#[cfg(not(feature = "security"))]
pub fn run(_args: KeysArgs) -> Result<(), crate::Error> {
    Err(crate::Error::Usage(
        "rl keys: this rl was built without the `security` feature".into(),
    ))
}

#[cfg(feature = "security")]
fn validity(common: &Common) -> Result<rl_layer::security::keys::Validity, crate::Error> {
    use rl_layer::security::keys::Validity;
    let Some(date) = &common.not_before else {
        return Ok(Validity::from_now(common.days));
    };
    let format = time::macros::format_description!("[year]-[month]-[day]");
    let day = time::Date::parse(date, format).map_err(|e| {
        crate::Error::Usage(format!("--not-before {date}: must be YYYY-MM-DD ({e})"))
    })?;
    Ok(Validity {
        not_before: day.midnight().assume_utc(),
        days: common.days,
    })
}

#[cfg(feature = "security")]
pub fn run(args: KeysArgs) -> Result<(), crate::Error> {
    use rl_layer::security::documents::Grantee;
    use rl_layer::security::keys;
    let usage = |e: keys::KeysError| crate::Error::Usage(format!("rl keys: {e}"));
    let written = match &args.action {
        KeysAction::Init { dir, common } => {
            let config = crate::cli::load_config(common.config.as_deref(), None)?;
            keys::init(dir, &config.dds, validity(common)?).map_err(usage)?
        }
        KeysAction::Add {
            dir,
            id,
            app,
            common,
        } => {
            let config = crate::cli::load_config(common.config.as_deref(), None)?;
            let grantee = match (id, app) {
                (Some(id), _) => Grantee::Controller(*id),
                (None, Some(name)) => {
                    let valid = !name.is_empty()
                        && name.len() <= 64
                        && name
                            .chars()
                            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
                    if !valid {
                        return Err(crate::Error::Usage(format!(
                            "--app {name:?}: must be 1..=64 letters, digits, '-' or '_'"
                        )));
                    }
                    Grantee::Application(name.clone())
                }
                (None, None) => return Err(crate::Error::Usage("--id or --app is needed".into())),
            };
            let target = keys::add(dir, &config.dds, &grantee, validity(common)?).map_err(usage)?;
            vec![target]
        }
    };
    for path in written {
        println!("{}", path.display());
    }
    Ok(())
}
