//! What the studio lets in: files only under the root given at start,
//! requests that carry the token printed in the URL (loopback included,
//! unless started with `--no-token`), whose `Host` names this studio and
//! that no other site's page made (`Origin`, `Sec-Fetch-Site`).

use std::path::{Component, Path, PathBuf};

/// Why a file name is refused, with the HTTP status it earns.
#[derive(Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Malformed (empty, NUL, backslash): 400.
    Bad(String),
    /// Leaves the root (`..`, absolute, a symlink out): 403.
    Outside(String),
    /// Does not exist: 404.
    Missing(String),
}

/// `rel` resolved under `root` (canonical): a relative path of normal
/// components whose real location (symlinks followed) is inside `root`.
pub fn resolve(root: &Path, rel: &str) -> Result<PathBuf, Refusal> {
    if rel.is_empty() {
        return Err(Refusal::Bad("no file named".into()));
    }
    if rel.contains('\0') || rel.contains('\\') {
        return Err(Refusal::Bad(format!(
            "{rel:?}: NUL or backslash in a file name"
        )));
    }
    let p = Path::new(rel);
    for c in p.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            Component::ParentDir => {
                return Err(Refusal::Outside(format!("{rel:?}: `..` is not allowed")))
            }
            Component::RootDir | Component::Prefix(_) => {
                return Err(Refusal::Outside(format!(
                    "{rel:?}: absolute paths are not allowed; name a file under the studio's root"
                )))
            }
        }
    }
    let joined = root.join(p);
    let real = joined
        .canonicalize()
        .map_err(|e| Refusal::Missing(format!("{rel:?}: {e}")))?;
    if !real.starts_with(root) {
        return Err(Refusal::Outside(format!(
            "{rel:?} leads outside the studio's root (a symlink out)"
        )));
    }
    if !real.is_file() {
        return Err(Refusal::Bad(format!("{rel:?} is not a file")));
    }
    Ok(real)
}

/// True when the raw request path holds an encoded slash or backslash
/// (`%2F`, `%5C`): refused before routing, so no decoding step can turn
/// one segment into two.
pub fn has_encoded_separator(raw_path: &str) -> bool {
    let l = raw_path.to_ascii_lowercase();
    l.contains("%2f") || l.contains("%5c") || l.contains("%00")
}

/// A fresh random token: 32 hex digits (128 bits) from the operating
/// system's random source (`getrandom(2)` on Linux, `/dev/urandom`
/// elsewhere). There is no weaker fallback: without that source the
/// studio does not start.
pub fn new_token() -> Result<String, String> {
    let mut bytes = [0u8; 16];
    os_random(&mut bytes)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

#[cfg(target_os = "linux")]
fn os_random(buf: &mut [u8]) -> Result<(), String> {
    let mut filled = 0;
    while filled < buf.len() {
        let rest = &mut buf[filled..];
        // SAFETY: getrandom writes at most `rest.len()` bytes into `rest`,
        // which is valid for writes of that length.
        let n = unsafe { libc::getrandom(rest.as_mut_ptr().cast(), rest.len(), 0) };
        if n < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            return Err(format!(
                "the operating system's random source (getrandom): {e}"
            ));
        }
        filled += n as usize;
    }
    Ok(())
}

#[cfg(not(target_os = "linux"))]
fn os_random(buf: &mut [u8]) -> Result<(), String> {
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| std::io::Read::read_exact(&mut f, buf))
        .map_err(|e| format!("the operating system's random source (/dev/urandom): {e}"))
}

/// The host name of a `Host` header's value, lowercase, without its port,
/// brackets or a trailing dot (`[::1]:8080` is `::1`, `LocalHost.:80` is
/// `localhost`); `None` when it is not a host[:port] at all.
pub fn host_name(host: &str) -> Option<String> {
    let host = host.trim();
    let name = if let Some(rest) = host.strip_prefix('[') {
        let (inside, after) = rest.split_once(']')?;
        if !(after.is_empty() || after.strip_prefix(':').is_some_and(is_port)) {
            return None;
        }
        inside
    } else {
        match host.rsplit_once(':') {
            Some((n, p)) if is_port(p) && !n.contains(':') => n,
            Some(_) => return None,
            None => host,
        }
    };
    let name = name.strip_suffix('.').unwrap_or(name).to_ascii_lowercase();
    let ok = !name.is_empty()
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-._:".contains(&b));
    ok.then_some(name)
}

fn is_port(p: &str) -> bool {
    !p.is_empty() && p.len() <= 5 && p.bytes().all(|b| b.is_ascii_digit())
}

/// Which `Host` headers the studio answers: DNS rebinding makes a
/// browser send a page's own name (`Host: attacker.example`) to this
/// machine's address, so only names that mean this studio are let in.
#[derive(Clone, Debug)]
pub struct Hosts {
    /// The address listened on.
    pub bound: std::net::IpAddr,
    /// Names given with `--allow-host` (lowercase, no port).
    pub allowed: Vec<String>,
}

impl Hosts {
    /// Whether `host` (a `Host` header's value) names this studio:
    /// `localhost`, the address listened on, any loopback address when
    /// listening on one, any address literal when listening on all of them
    /// (`0.0.0.0`, `::`: a browser that sends an address has been pointed
    /// at that address, not at a name someone else controls), or a name
    /// given with `--allow-host`. The port is not compared: behind an SSH
    /// tunnel the browser's port is the tunnel's.
    pub fn accepts(&self, host: &str) -> bool {
        let Some(name) = host_name(host) else {
            return false;
        };
        if name == "localhost" || self.allowed.contains(&name) {
            return true;
        }
        match name.parse::<std::net::IpAddr>() {
            Ok(ip) => {
                ip == self.bound
                    || (self.bound.is_loopback() && ip.is_loopback())
                    || self.bound.is_unspecified()
            }
            Err(_) => false,
        }
    }
}

/// Why a request from a browser is refused as cross-origin, if it is:
/// an `Origin` whose scheme, host and port are not the request's own
/// `Host` (a page of another site, or of another port of this machine),
/// an opaque `Origin: null`, or `Sec-Fetch-Site` other than `same-origin`
/// or `none` (`none`: the user typed the URL). Requests without these
/// headers (curl, scripts) are not a browser's cross-origin requests.
pub fn cross_origin(origin: Option<&str>, fetch_site: Option<&str>, host: &str) -> Option<String> {
    let site_refused = || {
        let site = fetch_site?.trim().to_ascii_lowercase();
        (site != "same-origin" && site != "none")
            .then(|| format!("Sec-Fetch-Site: {site} (a request made by another page)"))
    };
    let Some(origin) = origin else {
        return site_refused();
    };
    let origin = origin.trim();
    let own = |scheme: &str| -> bool {
        let Some(rest) = origin
            .strip_prefix(scheme)
            .and_then(|r| r.strip_prefix("://"))
        else {
            return false;
        };
        let default = if scheme == "https" { "443" } else { "80" };
        let with_port = |a: &str| -> String {
            let a = a.to_ascii_lowercase();
            let has_port = match a.rsplit_once(':') {
                Some((n, p)) => is_port(p) && (n.ends_with(']') || !n.contains(':')),
                None => false,
            };
            if has_port {
                a
            } else {
                format!("{a}:{default}")
            }
        };
        !rest.contains('/') && with_port(rest) == with_port(host.trim())
    };
    if own("http") || own("https") {
        site_refused()
    } else {
        Some(format!("Origin: {origin} is not this studio's own page"))
    }
}

/// Compares without stopping at the first difference.
pub fn same_token(given: &str, expected: &str) -> bool {
    let (a, b) = (given.as_bytes(), expected.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn refuses_what_leaves_the_root() {
        let d = tempfile::tempdir().unwrap();
        let root = d.path().canonicalize().unwrap();
        std::fs::write(root.join("a.y4m"), b"x").unwrap();
        assert!(resolve(&root, "a.y4m").is_ok());
        assert!(resolve(&root, "./a.y4m").is_ok());
        assert!(matches!(
            resolve(&root, "../a.y4m"),
            Err(Refusal::Outside(_))
        ));
        assert!(matches!(
            resolve(&root, "x/../../a"),
            Err(Refusal::Outside(_))
        ));
        assert!(matches!(
            resolve(&root, "/etc/passwd"),
            Err(Refusal::Outside(_))
        ));
        assert!(matches!(resolve(&root, "nope"), Err(Refusal::Missing(_))));
        assert!(matches!(resolve(&root, ""), Err(Refusal::Bad(_))));
        assert!(matches!(resolve(&root, "a\\b"), Err(Refusal::Bad(_))));
        assert!(has_encoded_separator("/api/x%2F..%2fy"));
        assert!(!has_encoded_separator("/api/info"));
        assert!(same_token("abc", "abc") && !same_token("abd", "abc") && !same_token("ab", "abc"));
        assert_eq!(new_token().unwrap().len(), 32);
        assert_ne!(new_token().unwrap(), new_token().unwrap());
    }

    #[test]
    fn hosts_and_origins() {
        let lo = Hosts {
            bound: "127.0.0.1".parse().unwrap(),
            allowed: vec!["studio.lan".into()],
        };
        for ok in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LOCALHOST.",
            "[::1]:9",
            "127.0.0.2",
            "studio.lan:1",
        ] {
            assert!(lo.accepts(ok), "{ok}");
        }
        for bad in [
            "attacker.example",
            "attacker.example:8080",
            "10.0.0.5:8080",
            "",
            "a b",
            "localhost:80:80",
            "[::1]x",
            "evil.localhost",
        ] {
            assert!(!lo.accepts(bad), "{bad}");
        }
        let all = Hosts {
            bound: "0.0.0.0".parse().unwrap(),
            allowed: vec![],
        };
        assert!(all.accepts("10.0.0.5:8080") && all.accepts("[fe80::1]:80"));
        assert!(!all.accepts("attacker.example:8080"));
        assert_eq!(host_name("[::1]:8080").as_deref(), Some("::1"));

        let h = "127.0.0.1:8080";
        assert!(cross_origin(None, None, h).is_none());
        assert!(cross_origin(Some("http://127.0.0.1:8080"), Some("same-origin"), h).is_none());
        assert!(cross_origin(None, Some("none"), h).is_none());
        assert!(cross_origin(Some("http://localhost:80"), None, "localhost").is_none());
        assert!(cross_origin(Some("http://127.0.0.1:9999"), None, h).is_some());
        assert!(cross_origin(Some("http://attacker.example"), None, h).is_some());
        assert!(cross_origin(Some("null"), None, h).is_some());
        assert!(cross_origin(Some("http://127.0.0.1:8080/x"), None, h).is_some());
        assert!(cross_origin(None, Some("same-site"), h).is_some());
        assert!(cross_origin(None, Some("cross-site"), h).is_some());
    }
}
