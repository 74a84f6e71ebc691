//! Who may drive the view: the person who started it, and nobody else.
//!
//! The server moves a physical arm, and any web page the person visits can send requests to
//! 127.0.0.1 from their browser. So, as Jupyter does:
//! - a random [`Token`] per run, printed in the page's URL on the first line of stdout, which
//!   every API request and the websocket must carry (`Authorization: Bearer T`, or `?token=T`
//!   where a browser cannot set a header: the websocket), compared in constant time;
//! - `Host` must name this server as it was reached ([`Access::host_ok`]): a DNS-rebinding page
//!   reaches 127.0.0.1 under its own name, and is refused;
//! - an `Origin` must be this server's own ([`Access::origin_ok`]): a page on another site is
//!   refused even if it somehow had the token;
//! - a POST's body must be `application/json` ([`json_content_type`]): a cross-site "simple"
//!   request (text/plain, form data) is refused without a preflight ever being needed.
//!
//! No CORS header is ever sent, so a browser never lets another site read an answer either.

use std::net::{IpAddr, SocketAddr};

use anyhow::{bail, Result};

/// Bytes of randomness in a generated token: 192 bits, as Jupyter's.
const TOKEN_BYTES: usize = 24;
/// The shortest token `--token` takes: 32 characters of the URL-safe set carry more than 128 bits
/// only if chosen at random, which is the user's part; shorter is refused outright.
pub const MIN_TOKEN_CHARS: usize = 32;

/// The secret of one run.
#[derive(Clone)]
pub struct Token(String);

impl std::fmt::Debug for Token {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never in a log by accident.
        f.write_str("Token(..)")
    }
}

impl Token {
    /// A new token from the operating system's generator, as hex.
    pub fn generate() -> Result<Self> {
        let mut bytes = [0u8; TOKEN_BYTES];
        getrandom::fill(&mut bytes).map_err(|e| anyhow::anyhow!("cannot draw a random token from the OS: {e}"))?;
        Ok(Self(bytes.iter().map(|b| format!("{b:02x}")).collect()))
    }

    /// A token the user chose (`--token`): long enough, and of characters that need no escaping
    /// in a URL.
    pub fn given(text: &str) -> Result<Self> {
        if text.len() < MIN_TOKEN_CHARS {
            bail!("--token: {} characters; at least {MIN_TOKEN_CHARS} are needed", text.len());
        }
        if let Some(c) = text.chars().find(|c| !(c.is_ascii_alphanumeric() || "-._~".contains(*c))) {
            bail!("--token: {c:?} is not allowed; use letters, digits and - . _ ~");
        }
        Ok(Self(text.to_string()))
    }

    /// The token's text, for the URL printed to the person.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// Whether `offered` is this token, in a time that does not depend on where they differ.
    pub fn matches(&self, offered: &str) -> bool {
        let (a, b) = (self.0.as_bytes(), offered.as_bytes());
        // The length is not secret (every generated token has the same); the content is.
        if a.len() != b.len() {
            return false;
        }
        a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
    }
}

/// The token a request carries: `Authorization: Bearer T`, else a `token` parameter of the query.
pub fn offered_token<'a>(authorization: Option<&'a str>, query: Option<&'a str>) -> Option<&'a str> {
    if let Some(value) = authorization {
        return value.strip_prefix("Bearer ").map(str::trim);
    }
    query?.split('&').find_map(|pair| pair.strip_prefix("token="))
}

/// Whether a `Content-Type` is JSON (`application/json`, parameters allowed).
pub fn json_content_type(value: Option<&str>) -> bool {
    value.and_then(|v| v.split(';').next()).is_some_and(|kind| kind.trim().eq_ignore_ascii_case("application/json"))
}

/// The names this server answers to.
#[derive(Clone, Debug)]
pub struct Access {
    port: u16,
    /// The address given to `--listen`, unless it is unspecified (0.0.0.0 or ::).
    listen: Option<IpAddr>,
}

impl Access {
    /// For a server bound to `bound` (the port picked when 0 was asked).
    pub fn new(bound: SocketAddr) -> Self {
        Self { port: bound.port(), listen: Some(bound.ip()).filter(|ip| !ip.is_unspecified()) }
    }

    /// Whether `host` (a `Host` header's value, or an `Origin`'s host) names this server as a
    /// connection to `local` reached it: 127.0.0.1, localhost, [::1], the listen address or the
    /// address the connection came in on, each with the server's port. A DNS name other than
    /// localhost is refused: that is what a rebinding page uses.
    pub fn host_ok(&self, host: &str, local: IpAddr) -> bool {
        let Some((name, port)) = split_host_port(host) else { return false };
        if port != self.port {
            return false;
        }
        if name.eq_ignore_ascii_case("localhost") {
            return true;
        }
        let Ok(ip) = name.parse::<IpAddr>() else { return false };
        ip.is_loopback() || Some(ip) == self.listen || ip == local
    }

    /// Whether an `Origin` header is this server's own (`http://` and a host as for
    /// [`Self::host_ok`]). `null` and every other scheme are refused.
    pub fn origin_ok(&self, origin: &str, local: IpAddr) -> bool {
        origin.strip_prefix("http://").is_some_and(|host| self.host_ok(host, local))
    }
}

/// `name:port`, `[v6]:port`; the port is required (the server never listens on port 80 by default,
/// and a browser always sends it otherwise).
fn split_host_port(host: &str) -> Option<(&str, u16)> {
    let (name, port) = match host.strip_prefix('[') {
        Some(rest) => {
            let (name, after) = rest.split_once(']')?;
            (name, after.strip_prefix(':')?)
        }
        None => host.rsplit_once(':')?,
    };
    if name.is_empty() || port.is_empty() || !port.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some((name, port.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    const LOOPBACK: IpAddr = IpAddr::V4(std::net::Ipv4Addr::LOCALHOST);

    #[test]
    fn tokens_are_random_long_and_compared_whole() {
        let (a, b) = (Token::generate().unwrap(), Token::generate().unwrap());
        assert_eq!(a.as_str().len(), 2 * TOKEN_BYTES);
        assert_ne!(a.as_str(), b.as_str());
        assert!(a.matches(a.as_str()));
        assert!(!a.matches(b.as_str()));
        assert!(!a.matches(&a.as_str()[1..]));
        assert!(!a.matches(&format!("{}0", a.as_str())));
        assert!(!a.matches(""));
        assert_eq!(format!("{a:?}"), "Token(..)");
    }

    #[test]
    fn a_given_token_is_long_and_url_safe() {
        assert!(Token::given(&"a".repeat(MIN_TOKEN_CHARS)).is_ok());
        assert!(Token::given("short").unwrap_err().to_string().contains("at least 32"));
        assert!(Token::given(&format!("{}&x", "a".repeat(40))).unwrap_err().to_string().contains("'&'"));
    }

    #[test]
    fn the_token_is_read_from_the_header_or_the_query() {
        assert_eq!(offered_token(Some("Bearer abc"), None), Some("abc"));
        assert_eq!(offered_token(Some("Basic abc"), Some("token=x")), None, "a header that is not ours wins");
        assert_eq!(offered_token(None, Some("a=1&token=xyz")), Some("xyz"));
        assert_eq!(offered_token(None, Some("tokens=xyz")), None);
        assert_eq!(offered_token(None, None), None);
    }

    #[test]
    fn only_json_bodies() {
        assert!(json_content_type(Some("application/json")));
        assert!(json_content_type(Some("Application/JSON; charset=utf-8")));
        for refused in [None, Some("text/plain"), Some("application/x-www-form-urlencoded"), Some("application/jsonp")]
        {
            assert!(!json_content_type(refused), "{refused:?}");
        }
    }

    #[test]
    fn host_names_the_server_as_reached() {
        let access = Access::new("127.0.0.1:8765".parse().unwrap());
        for good in ["127.0.0.1:8765", "localhost:8765", "LOCALHOST:8765", "[::1]:8765"] {
            assert!(access.host_ok(good, LOOPBACK), "{good}");
        }
        for bad in [
            "evil.example:8765",
            "127.0.0.1:80",
            "127.0.0.1",
            "localhost",
            "127.0.0.1:8765x",
            ":8765",
            "[::1:8765",
            "localhost.evil.example:8765",
            "",
        ] {
            assert!(!access.host_ok(bad, LOOPBACK), "{bad}");
        }
        // --listen 0.0.0.0: the address the connection came in on, and no other.
        let lan: IpAddr = "192.0.2.7".parse().unwrap();
        let any = Access::new("0.0.0.0:9000".parse().unwrap());
        assert!(any.host_ok("192.0.2.7:9000", lan));
        assert!(!any.host_ok("192.0.2.8:9000", lan));
        assert!(!any.host_ok("0.0.0.0:9000", lan));
        let given = Access::new("192.0.2.7:9000".parse().unwrap());
        assert!(given.host_ok("192.0.2.7:9000", LOOPBACK));
    }

    proptest::proptest! {
        /// Any Host or Origin: a clear yes or no, and yes only for this server's names and port.
        #[test]
        fn random_hosts_are_judged_without_panic(host in "\\PC{0,40}", port in proptest::prelude::any::<u16>()) {
            let access = Access::new("127.0.0.1:8765".parse().unwrap());
            if access.host_ok(&host, LOOPBACK) {
                proptest::prop_assert!(host.ends_with(":8765"), "{host}");
            }
            let candidate = format!("{host}:{port}");
            if access.host_ok(&candidate, LOOPBACK) {
                proptest::prop_assert_eq!(port, 8765);
            }
            let _ = access.origin_ok(&host, LOOPBACK);
        }

        /// A token matches itself and nothing else.
        #[test]
        fn a_token_matches_only_itself(offered in "[0-9a-f]{0,60}") {
            let token = Token::generate().unwrap();
            proptest::prop_assert_eq!(token.matches(&offered), offered == token.as_str());
        }
    }

    #[test]
    fn origin_is_the_servers_own() {
        let access = Access::new("127.0.0.1:8765".parse().unwrap());
        assert!(access.origin_ok("http://127.0.0.1:8765", LOOPBACK));
        assert!(access.origin_ok("http://localhost:8765", LOOPBACK));
        for bad in
            ["http://evil.example", "http://evil.example:8765", "null", "https://127.0.0.1:8765", "127.0.0.1:8765"]
        {
            assert!(!access.origin_ok(bad, LOOPBACK), "{bad}");
        }
    }
}
