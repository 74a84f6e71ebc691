//! Rust's legacy symbol mangling read back as paths: llvm-objdump's rendering of a symbol
//! ([`pretty`], for `armctl footprint`'s call chains) and a raw ELF symbol name ([`legacy_path`],
//! for finding a function in a firmware ELF).

/// A readable Rust path from llvm-objdump's rendering of a legacy-mangled symbol: the `::h<hash>`
/// suffix dropped and the `$LT$`-style escapes decoded
/// (`Motion$LT$T$C$_$GT$::sample::h58..` becomes `Motion<T,_>::sample`).
pub fn pretty(symbol: &str) -> String {
    let symbol = match symbol.rsplit_once("::h") {
        Some((path, hash)) if hash.len() == 16 && hash.bytes().all(|b| b.is_ascii_hexdigit()) => path,
        _ => symbol,
    };
    if !symbol.contains('$') && !symbol.contains("..") {
        return symbol.to_string();
    }
    const ESCAPES: [(&str, &str); 9] = [
        ("$LT$", "<"),
        ("$GT$", ">"),
        ("$C$", ","),
        ("$RF$", "&"),
        ("$BP$", "*"),
        ("$SP$", "@"),
        ("$LP$", "("),
        ("$RP$", ")"),
        ("..", "::"),
    ];
    let mut text = symbol.to_string();
    for (from, to) in ESCAPES {
        text = text.replace(from, to);
    }
    // `$u20$`-style: a character by its hex code.
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find("$u") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 2..];
        match after
            .split_once('$')
            .and_then(|(hex, tail)| Some((char::from_u32(u32::from_str_radix(hex, 16).ok()?)?, tail)))
        {
            Some((c, tail)) => {
                out.push(c);
                rest = tail;
            }
            None => {
                out.push_str("$u");
                rest = after;
            }
        }
    }
    out.push_str(rest);
    // A leading `_` escapes a path segment that starts with `<` (`_<impl [T]>`).
    out.replace("::_<", "::<")
}

/// The Rust path of a legacy-mangled symbol (`_ZN16board_mps2_an3865start17h0123456789abcdefE`
/// is `board_mps2_an386::start`), its hash dropped and its escapes decoded as
/// [`pretty`] decodes llvm-objdump's; `None` for any other name.
pub fn legacy_path(symbol: &str) -> Option<String> {
    let mut rest = symbol.strip_prefix("_ZN")?.strip_suffix('E')?;
    let mut parts = Vec::new();
    while !rest.is_empty() {
        let digits = rest.find(|c: char| !c.is_ascii_digit())?;
        let len: usize = rest[..digits].parse().ok()?;
        let part = rest.get(digits..digits + len)?;
        parts.push(part);
        rest = &rest[digits + len..];
    }
    Some(pretty(&parts.join("::")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legacy_symbols_read_as_rust_paths() {
        assert_eq!(
            pretty("kinematics::trajectory::player::Motion$LT$T$C$_$GT$::sample::h5898737983f83987"),
            "kinematics::trajectory::player::Motion<T,_>::sample"
        );
        assert_eq!(
            pretty("core::slice::_$LT$impl$u20$$u5b$T$u5d$$GT$::copy_from_slice::len_mismatch_fail::h0123456789abcdef"),
            "core::slice::<impl [T]>::copy_from_slice::len_mismatch_fail"
        );
        assert_eq!(pretty("main"), "main");
    }

    #[test]
    fn a_legacy_mangled_symbol_reads_as_its_rust_path() {
        assert_eq!(
            legacy_path("_ZN16board_mps2_an3865start17h0123456789abcdefE").as_deref(),
            Some("board_mps2_an386::start")
        );
        assert_eq!(
            legacy_path("_ZN8firmware5board9main_loop17MainLoop$LT$T$GT$3run17h0123456789abcdefE").as_deref(),
            Some("firmware::board::main_loop::MainLoop<T>::run")
        );
        assert_eq!(legacy_path("injected_panic"), None);
        assert_eq!(legacy_path("_ZN99shortE"), None, "a length past the end");
    }
}
