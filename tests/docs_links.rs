//! Every relative link and image in the README and the manual (`docs/*.md`) points at a file that
//! exists, and every `#fragment` on a link to a markdown file (or a bare `#fragment`, to the same
//! file) names one of its headings.
//!
//! The manual is many files that link to each other and to the source; a file renamed or a
//! heading reworded would otherwise leave a link that leads nowhere, which nobody notices until a
//! reader follows it. Links to the web (`http:`, `https:`, `mailto:`) are not followed: the tests
//! run offline. Links inside code (fenced or indented blocks, and `code spans`) are not links.
//!
//! The parser is small and written here, for the markdown this project writes: inline links
//! `[text](target)` and images `![alt](target)`, with an optional `<...>` around the target and an
//! optional title after it, and reference definitions `[name]: target`.

use std::path::{Path, PathBuf};

/// One link found in a markdown text.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Link {
    /// 1-based line of the `](` (or of the reference definition).
    line: usize,
    /// The target as written, without `<...>` and title.
    target: String,
    image: bool,
}

/// The text with code blocks and code spans blanked out (spaces, newlines kept), so that the
/// link finder sees only prose and every offset keeps its line.
fn without_code(text: &str) -> String {
    blank_code_spans(&without_code_blocks(text))
}

/// The text with fenced and indented code blocks blanked out, code spans kept.
fn without_code_blocks(text: &str) -> String {
    let lines: Vec<&str> = text.split('\n').collect();
    let mut kept: Vec<String> = Vec::with_capacity(lines.len());
    let mut fence: Option<(char, usize)> = None;
    let mut in_list = false;
    let mut in_indented_code = false;
    let mut previous_blank = true;
    for line in &lines {
        let blank = line.trim().is_empty();
        let indent = line.len() - line.trim_start_matches([' ', '\t']).len();
        let trimmed = line.trim_start();
        let fence_run = |c: char| trimmed.chars().take_while(|&x| x == c).count();
        let blanked = " ".repeat(line.len());
        if let Some((c, n)) = fence {
            // Inside a fenced block: it ends at a run of the same character at least as long.
            if indent < 4 && fence_run(c) >= n && trimmed.trim_end().chars().all(|x| x == c) {
                fence = None;
            }
            kept.push(blanked);
            previous_blank = blank;
            continue;
        }
        if indent < 4 && (fence_run('`') >= 3 || fence_run('~') >= 3) {
            let c = trimmed.chars().next().unwrap_or('`');
            fence = Some((c, fence_run(c)));
            kept.push(blanked);
            previous_blank = false;
            continue;
        }
        if blank {
            kept.push(String::new());
            previous_blank = true;
            continue;
        }
        let list_item = is_list_item(trimmed);
        if indent == 0 && !list_item && previous_blank {
            in_list = false;
        }
        if list_item {
            in_list = true;
        }
        // An indented code block: four spaces or a tab after a blank line (or continuing one),
        // outside a list, where indented lines are the items' own paragraphs and code.
        let indented_code = indent >= 4 && !in_list && (previous_blank || in_indented_code) && !list_item;
        in_indented_code = indented_code;
        kept.push(if indented_code { blanked } else { line.to_string() });
        previous_blank = false;
    }
    kept.join("\n")
}

fn is_list_item(trimmed: &str) -> bool {
    if let Some(rest) = trimmed.strip_prefix(['-', '*', '+']) {
        return rest.starts_with(' ') || rest.is_empty();
    }
    let digits = trimmed.chars().take_while(char::is_ascii_digit).count();
    digits > 0 && {
        let rest = &trimmed[digits..];
        (rest.starts_with(". ") || rest.starts_with(") ")) && digits <= 9
    }
}

/// Code spans blanked: a run of n backticks opens one, the next run of exactly n closes it. A
/// span does not cross a blank line; a run with no closing run in its paragraph is plain text.
fn blank_code_spans(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = bytes.to_vec();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] != b'`' {
            i += 1;
            continue;
        }
        let n = bytes[i..].iter().take_while(|&&b| b == b'`').count();
        let mut j = i + n;
        let mut close = None;
        while j < bytes.len() {
            if bytes[j] == b'\n' && bytes.get(j + 1) == Some(&b'\n') {
                break;
            }
            if bytes[j] == b'`' {
                let m = bytes[j..].iter().take_while(|&&b| b == b'`').count();
                if m == n {
                    close = Some(j);
                    break;
                }
                j += m;
            } else {
                j += 1;
            }
        }
        match close {
            Some(j) => {
                for b in &mut out[i..j + n] {
                    if *b != b'\n' {
                        *b = b' ';
                    }
                }
                i = j + n;
            }
            None => i += n,
        }
    }
    // Every byte of a span (all of a multi-byte character too) became a space: still UTF-8.
    String::from_utf8(out).expect("blanking whole spans keeps UTF-8")
}

/// Every inline link, image and reference definition outside code, in order.
fn find_links(text: &str) -> Vec<Link> {
    let prose = without_code(text);
    let bytes = prose.as_bytes();
    let line_of = |offset: usize| 1 + bytes[..offset].iter().filter(|&&b| b == b'\n').count();
    let mut links = Vec::new();
    let mut search = 0;
    while let Some(found) = prose[search..].find("](") {
        let close_bracket = search + found;
        let start = close_bracket + 2;
        search = start;
        let Some(open_bracket) = matching_open_bracket(bytes, close_bracket) else {
            continue;
        };
        let image = open_bracket > 0 && bytes[open_bracket - 1] == b'!';
        // The target: `<...>`, or up to the first space (a title follows) or the `)` that
        // balances the parentheses opened inside it.
        let rest = &prose[start..];
        let target = if let Some(angled) = rest.strip_prefix('<') {
            match angled.find('>') {
                Some(end) => angled[..end].to_string(),
                None => continue,
            }
        } else {
            let mut depth = 0usize;
            let mut end = None;
            for (k, c) in rest.char_indices() {
                match c {
                    '(' => depth += 1,
                    ')' if depth == 0 => {
                        end = Some(k);
                        break;
                    }
                    ')' => depth -= 1,
                    ' ' | '\n' | '\t' => {
                        end = Some(k);
                        break;
                    }
                    _ => {}
                }
            }
            match end {
                Some(end) => rest[..end].to_string(),
                None => continue,
            }
        };
        links.push(Link { line: line_of(close_bracket), target, image });
    }
    // Reference definitions: `[name]: target` at the start of a line.
    let mut offset = 0;
    for line in prose.split('\n') {
        let trimmed = line.trim_start();
        if trimmed.starts_with('[') && !trimmed.starts_with("[^") {
            if let Some(end) = trimmed.find("]:") {
                if let Some(target) = trimmed[end + 2..].split_whitespace().next() {
                    let target = target.trim_start_matches('<').trim_end_matches('>');
                    links.push(Link { line: line_of(offset), target: target.to_string(), image: false });
                }
            }
        }
        offset += line.len() + 1;
    }
    links.sort_by_key(|l| l.line);
    links
}

/// The `[` that opens the text ending at `close`, with brackets inside it balanced; none when the
/// paragraph has none (then `](` was not a link).
fn matching_open_bracket(bytes: &[u8], close: usize) -> Option<usize> {
    let mut depth = 0usize;
    let mut k = close;
    while k > 0 {
        k -= 1;
        match bytes[k] {
            b']' => depth += 1,
            b'[' if depth == 0 => return Some(k),
            b'[' => depth -= 1,
            b'\n' if k > 0 && bytes[k - 1] == b'\n' => return None,
            _ => {}
        }
    }
    None
}

/// Whether a target leaves the repository (a web address or mail), or stays in the same file.
fn is_relative(target: &str) -> bool {
    let lower = target.to_ascii_lowercase();
    !(lower.starts_with("http:")
        || lower.starts_with("https:")
        || lower.starts_with("mailto:")
        || lower.starts_with("//")
        || target.starts_with('#')
        || target.is_empty())
}

/// GitHub's anchors of a markdown file's headings: the heading's text in lower case, every
/// character that is not a letter, a digit, a space, `-` or `_` dropped, spaces made `-`; a
/// repeated anchor gets `-1`, `-2`, ... Headings in code blocks are not headings.
fn anchors(text: &str) -> Vec<String> {
    let mut counts: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    let mut slugs = Vec::new();
    for line in without_code_blocks(text).split('\n') {
        let trimmed = line.trim_start();
        let hashes = trimmed.chars().take_while(|&c| c == '#').count();
        if hashes == 0 || hashes > 6 || !trimmed[hashes..].starts_with(' ') {
            continue;
        }
        let heading = trimmed[hashes..].trim().trim_end_matches('#').trim();
        let base: String = heading
            .to_lowercase()
            .chars()
            .filter(|&c| c.is_alphanumeric() || c == ' ' || c == '-' || c == '_')
            .map(|c| if c == ' ' { '-' } else { c })
            .collect();
        let repeats = counts.entry(base.clone()).or_insert(0);
        slugs.push(if *repeats == 0 { base.clone() } else { format!("{base}-{repeats}") });
        *repeats += 1;
    }
    slugs
}

/// The broken links of one markdown text that lives in `dir`, as `NAME:LINE: TARGET (why)`.
fn broken_links(dir: &Path, name: &str, text: &str) -> (usize, Vec<String>) {
    let mut checked = 0;
    let mut broken = Vec::new();
    for link in find_links(text) {
        if let Some(fragment) = link.target.strip_prefix('#') {
            // Within the same file.
            if !anchors(text).iter().any(|a| a == fragment) {
                broken.push(format!("{name}:{}: {} (no heading here has that anchor)", link.line, link.target));
            }
            continue;
        }
        if !is_relative(&link.target) {
            continue;
        }
        checked += 1;
        let (path, fragment) = match link.target.split_once('#') {
            Some((p, f)) => (p, Some(f)),
            None => (link.target.as_str(), None),
        };
        let path = path.split_once('?').map_or(path, |(p, _)| p);
        let resolved: PathBuf = dir.join(path);
        if !resolved.exists() {
            broken.push(format!("{name}:{}: {} (no such file: {})", link.line, link.target, resolved.display()));
            continue;
        }
        if let Some(fragment) = fragment {
            if resolved.extension().is_some_and(|e| e == "md") && resolved.is_file() {
                let target_text = std::fs::read_to_string(&resolved).unwrap_or_default();
                if !anchors(&target_text).iter().any(|a| a == fragment) {
                    broken.push(format!(
                        "{name}:{}: {} (no heading in {} has the anchor #{fragment})",
                        link.line,
                        link.target,
                        resolved.display()
                    ));
                }
            }
        }
    }
    (checked, broken)
}

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// README.md and every docs/*.md, in a fixed order.
fn documents() -> Vec<PathBuf> {
    let root = repository();
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/ exists")
        .map(|e| e.expect("a docs/ entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    let mut all = vec![root.join("README.md")];
    all.extend(docs);
    all
}

#[test]
fn every_relative_link_in_the_readme_and_the_manual_points_at_a_file() {
    let root = repository();
    let mut checked = 0;
    let mut images = 0;
    let mut broken = Vec::new();
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).expect("a readable markdown file");
        let name = doc.strip_prefix(&root).unwrap_or(&doc).display().to_string();
        images += find_links(&text).iter().filter(|l| l.image && is_relative(&l.target)).count();
        let (n, mut b) = broken_links(doc.parent().expect("a folder"), &name, &text);
        checked += n;
        broken.append(&mut b);
    }
    assert!(broken.is_empty(), "{} broken link(s) in README.md and docs/:\n{}", broken.len(), broken.join("\n"));
    // The manual links its pages to each other and shows two images: finding fewer means the
    // finder stopped finding, not that the links are fine.
    assert!(checked >= 30, "only {checked} relative links found in README.md and docs/");
    assert!(images >= 2, "only {images} relative images found in README.md and docs/");
}

#[test]
fn the_link_finder_finds_links_and_images_and_skips_code() {
    let text = "\
# A title

See [the front page](README.md) and [a gone page](no-such-file.md), and
![a picture](docs/view.png \"with a title\").
Not followed: `[code](span.md)`, [the web](https://example.com/x.md), [mail](mailto:a@b.c),
[here](#a-title), [nowhere](#no-such-title) and a [bracket] (with a space).
A span across lines: `one
[two](span2.md)` ends here.

```toml
[table](fenced.md)
```

    [indented](indented.md)

- a list item
    [in the item](docs/README.md#the-manual)
";
    let found: Vec<(usize, String, bool)> = find_links(text).into_iter().map(|l| (l.line, l.target, l.image)).collect();
    assert_eq!(
        found,
        vec![
            (3, "README.md".to_string(), false),
            (3, "no-such-file.md".to_string(), false),
            (4, "docs/view.png".to_string(), true),
            (5, "https://example.com/x.md".to_string(), false),
            (5, "mailto:a@b.c".to_string(), false),
            (6, "#a-title".to_string(), false),
            (6, "#no-such-title".to_string(), false),
            (17, "docs/README.md#the-manual".to_string(), false),
        ]
    );
    let (checked, broken) = broken_links(&repository(), "sample.md", text);
    assert_eq!(checked, 4, "README.md, no-such-file.md, docs/view.png, docs/README.md#the-manual");
    assert_eq!(broken.len(), 2, "{broken:?}");
    assert!(broken[0].starts_with("sample.md:3: no-such-file.md (no such file"), "{broken:?}");
    assert!(broken[1].starts_with("sample.md:6: #no-such-title (no heading"), "{broken:?}");

    let (_, broken) = broken_links(&repository(), "sample.md", "[x](docs/README.md#no-such-heading)\n");
    assert_eq!(broken.len(), 1, "{broken:?}");
    assert!(broken[0].contains("no heading"), "{broken:?}");
}

#[test]
fn anchors_are_made_as_github_makes_them() {
    let text = "\
# The arm file (TOML)
## Servo tools: `armctl servo`
## `armctl_follower`, a LeRobot robot
## Tests
### Tests
```
# not a heading
```
";
    assert_eq!(
        anchors(text),
        vec!["the-arm-file-toml", "servo-tools-armctl-servo", "armctl_follower-a-lerobot-robot", "tests", "tests-1"]
    );
}
