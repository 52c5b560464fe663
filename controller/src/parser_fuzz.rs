//! Property tests of the parsers of outside input written by hand: hand layouts, configs and
//! task scripts. Any text, and any mutation of a shipped file, gives a value or a typed
//! error, never a panic (`PROPTEST_CASES=100000` in `scripts/test`).

use std::sync::Arc;

use proptest::prelude::*;

use crate::config::{AppConfig, MemoryFiles};
use crate::layout::HandLayout;
use crate::registry::TransportRegistry;
use crate::task::script::TaskScript;

const LAYOUT: &str = include_str!("../../configs/layouts/three-finger.toml");
const CONFIG: &str = include_str!("../../configs/gelgripper-sim.toml");
const SCRIPT: &str = include_str!("../../configs/tasks/screwdriver.toml");

/// What insertions and replacements draw from: mostly TOML's own punctuation and digits,
/// which reach deeper into the parsers than random bytes.
const ALPHABET: &[u8] = b"[]=\"'.,#{}0123456789-+eE \n_abcxyz\\";

/// `text` with `edits` applied: each (position, kind, byte) deletes, inserts or replaces
/// one character (on character boundaries, so the result stays a string).
fn mutate(text: &str, edits: &[(usize, u8, u8)]) -> String {
    let mut chars: Vec<char> = text.chars().collect();
    for &(at, kind, byte) in edits {
        if chars.is_empty() {
            break;
        }
        let at = at % chars.len();
        let c = ALPHABET[usize::from(byte) % ALPHABET.len()] as char;
        match kind % 3 {
            0 => {
                chars.remove(at);
            }
            1 => chars.insert(at, c),
            _ => chars[at] = c,
        }
    }
    chars.into_iter().collect()
}

fn edits() -> impl Strategy<Value = Vec<(usize, u8, u8)>> {
    proptest::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..6)
}

fn layout() -> HandLayout {
    HandLayout::from_toml("three-finger.toml", LAYOUT).expect("the shipped layout")
}

proptest! {
    #[test]
    fn layouts_never_panic(e in edits(), noise in "\\PC{0,200}") {
        let _ = HandLayout::from_toml("l.toml", &mutate(LAYOUT, &e));
        let _ = HandLayout::from_toml("l.toml", &noise);
    }

    #[test]
    fn configs_never_panic(e in edits(), noise in "\\PC{0,200}") {
        let files = Arc::new(MemoryFiles(vec![(
            "layouts/three-finger.toml".into(),
            LAYOUT.into(),
        )]));
        let registry = TransportRegistry::new();
        for text in [mutate(CONFIG, &e), noise] {
            let _ = AppConfig::from_text("c.toml", &text, std::path::Path::new(""), files.clone(), &registry);
        }
    }

    #[test]
    fn task_scripts_never_panic(e in edits(), noise in "\\PC{0,200}") {
        let layout = layout();
        let _ = TaskScript::from_toml("s.toml", &mutate(SCRIPT, &e), &layout, 800.0);
        let _ = TaskScript::from_toml("s.toml", &noise, &layout, 800.0);
    }
}
