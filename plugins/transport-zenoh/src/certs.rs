//! A fleet's certificates for testing and first deployments (`skid fleet certs`): one CA, and for each
//! robot a key and a certificate the CA signs, whose common name `robot-<id>` is the identity the ACL
//! checks (see [`crate::access`]). ECDSA P-256 keys, made with `rcgen`; the CA key is written beside the
//! certificates so more robots can be added later, and must be kept off the robots.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use rcgen::{
    BasicConstraints, CertificateParams, DistinguishedName, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer,
    KeyPair, KeyUsagePurpose,
};
use skid_core::PluginError;

use crate::access::common_name;
use crate::config::TlsFiles;

/// The files of one robot, as `[transport.zenoh.tls]` names them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RobotFiles {
    pub robot: u32,
    pub certificate: PathBuf,
    pub private_key: PathBuf,
}

/// What [`write_fleet_certificates`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FleetFiles {
    pub ca_certificate: PathBuf,
    pub ca_private_key: PathBuf,
    pub robots: Vec<RobotFiles>,
}

impl FleetFiles {
    /// The `[transport.zenoh.tls]` files of robot `robot`, `None` when the fleet has no such robot.
    pub fn tls_for(&self, robot: u32) -> Option<TlsFiles> {
        let files = self.robots.iter().find(|files| files.robot == robot)?;
        Some(TlsFiles {
            ca_certificate: self.ca_certificate.clone(),
            certificate: files.certificate.clone(),
            private_key: files.private_key.clone(),
        })
    }
}

fn failed(what: &str, error: impl std::fmt::Display) -> PluginError {
    PluginError::failed("zenoh", format!("{what}: {error}"))
}

/// Validity from 1 January of this year to 1 January `years` later (UTC).
fn validity(params: &mut CertificateParams, years: i32) {
    let seconds = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |elapsed| elapsed.as_secs());
    // The calendar year, to within a day at New Year: enough for a validity window.
    let year = 1970 + i32::try_from(seconds / 31_556_952).unwrap_or(0);
    params.not_before = rcgen::date_time_ymd(year, 1, 1);
    params.not_after = rcgen::date_time_ymd(year + years, 1, 1);
}

fn named(name: &str) -> Result<CertificateParams, PluginError> {
    let mut params =
        CertificateParams::new(vec![name.to_owned()]).map_err(|e| failed("certificate name", e))?;
    let mut distinguished = DistinguishedName::new();
    distinguished.push(DnType::CommonName, name);
    distinguished.push(DnType::OrganizationName, "SKiD fleet");
    params.distinguished_name = distinguished;
    Ok(params)
}

fn write(path: &Path, text: &str) -> Result<(), PluginError> {
    std::fs::write(path, text).map_err(|e| failed(&format!("writing {}", path.display()), e))
}

/// A private key file readable by its owner only.
fn write_key(path: &Path, text: &str) -> Result<(), PluginError> {
    write(path, text)?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600))
            .map_err(|e| failed(&format!("restricting {}", path.display()), e))?;
    }
    Ok(())
}

/// Writes a CA (`ca.pem`, `ca.key`) and, for robots `0..robots`, `robot-<id>.pem` and `robot-<id>.key`
/// into `folder`, valid for `years` years. Existing files are overwritten.
pub fn write_fleet_certificates(folder: &Path, robots: u32, years: i32) -> Result<FleetFiles, PluginError> {
    std::fs::create_dir_all(folder).map_err(|e| failed(&format!("creating {}", folder.display()), e))?;
    let ca_key = KeyPair::generate().map_err(|e| failed("CA key", e))?;
    let mut ca_params = named("SKiD fleet CA")?;
    ca_params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca_params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    validity(&mut ca_params, years);
    let ca_certificate = ca_params
        .self_signed(&ca_key)
        .map_err(|e| failed("CA certificate", e))?;
    let files = FleetFiles {
        ca_certificate: folder.join("ca.pem"),
        ca_private_key: folder.join("ca.key"),
        robots: (0..robots)
            .map(|robot| RobotFiles {
                robot,
                certificate: folder.join(format!("{}.pem", common_name(robot))),
                private_key: folder.join(format!("{}.key", common_name(robot))),
            })
            .collect(),
    };
    write(&files.ca_certificate, &ca_certificate.pem())?;
    write_key(&files.ca_private_key, &ca_key.serialize_pem())?;
    let issuer = Issuer::new(ca_params, ca_key);
    for robot in &files.robots {
        let key = KeyPair::generate().map_err(|e| failed("robot key", e))?;
        let mut params = named(&common_name(robot.robot))?;
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        validity(&mut params, years);
        let certificate = params
            .signed_by(&key, &issuer)
            .map_err(|e| failed("robot certificate", e))?;
        write(&robot.certificate, &certificate.pem())?;
        write_key(&robot.private_key, &key.serialize_pem())?;
    }
    Ok(files)
}
