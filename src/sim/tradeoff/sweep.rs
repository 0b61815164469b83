//! Which settings the report measures: the defaults, every knob's other values one at a time,
//! the crossings of knobs that interact, and a few named presets.

use super::knobs::{Knob, Setting};

/// Knob pairs whose values interact, measured in every combination: the budget with the
/// pipeline precision (does float matter once triangles are coarse?) and with the crack mode
/// (coarser budgets mean more level changes to hide); perspective with the texture filter (both
/// decide the texels a pixel shows); the budget with the pixel-error bound (which of time and
/// error caps detail) and with the allocation (how the budget is shared matters most when it
/// is small).
pub const CROSSES: [[&str; 2]; 5] = [
    ["budget", "max-error"],
    ["budget", "allocation"],
    ["budget", "precision"],
    ["perspective", "filter"],
    ["budget", "cracks"],
];

/// Named combinations: the cheapest frame the knobs allow, and every optional feature off.
pub const PRESETS: [(&str, &[(&str, &str)]); 2] = [
    (
        "fastest",
        &[
            ("budget", "3000"),
            ("perspective", "affine"),
            ("filter", "nearest"),
            ("cracks", "none"),
        ],
    ),
    (
        "features-off",
        &[("texture", "off"), ("depth-test", "off"), ("fog", "off")],
    ),
];

/// One setting to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// `defaults`, a preset's name, or the changed knobs as `knob=value` joined by spaces.
    pub name: String,
    /// The knobs changed from the defaults, `(knob, value)`.
    pub changes: Vec<(&'static str, &'static str)>,
    /// The configuration.
    pub setting: Setting,
}

impl Entry {
    /// The value label of `knob` in this entry (a changed one, else `None`: the default).
    pub fn change(&self, knob: &str) -> Option<&'static str> {
        self.changes.iter().find(|c| c.0 == knob).map(|c| c.1)
    }
}

/// The settings to measure over `knobs` (all of them when `only` is `None`), each knob turned
/// from `defaults`; the defaults come first, and no configuration appears twice.
pub fn plan(knobs: &[Knob], only: Option<&[String]>, defaults: Setting) -> Vec<Entry> {
    let selected = |name: &str| only.is_none_or(|o| o.iter().any(|k| k == name));
    let find = |name: &str| knobs.iter().find(|k| k.name == name);
    let mut entries = vec![Entry {
        name: "defaults".into(),
        changes: Vec::new(),
        setting: defaults,
    }];
    let mut push = |name: Option<&str>, changes: Vec<(&'static str, &'static str)>| {
        let mut setting = defaults;
        let mut kept = Vec::new();
        for &(knob, label) in &changes {
            let k = find(knob).expect("sweep names existing knobs");
            let before = setting;
            (k.value(label).expect("sweep names existing values").apply)(&mut setting);
            if setting != before {
                kept.push((k.name, label));
            }
        }
        if entries.iter().any(|e| e.setting == setting) {
            return;
        }
        let label = kept
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ");
        entries.push(Entry {
            name: name.map_or(label, str::to_string),
            changes: kept,
            setting,
        });
    };
    for knob in knobs.iter().filter(|k| selected(k.name)) {
        for value in &knob.values {
            push(None, vec![(knob.name, value.label)]);
        }
    }
    for [a, b] in CROSSES {
        let (Some(ka), Some(kb)) = (find(a), find(b)) else {
            continue;
        };
        if !(selected(a) && selected(b)) {
            continue;
        }
        for va in &ka.values {
            for vb in &kb.values {
                push(None, vec![(ka.name, va.label), (kb.name, vb.label)]);
            }
        }
    }
    for (name, changes) in PRESETS {
        if changes
            .iter()
            .all(|(k, _)| selected(k) && find(k).is_some())
        {
            let changes = changes
                .iter()
                .map(|&(k, v)| {
                    let knob = find(k).expect("checked above");
                    (
                        knob.name,
                        knob.value(v).expect("presets name existing values").label,
                    )
                })
                .collect();
            push(Some(name), changes);
        }
    }
    entries
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::error_bound::ErrorBound;
    use crate::sim::tradeoff::knobs::knobs;

    #[test]
    fn one_at_a_time_then_crossings_without_repeats() {
        let knobs = knobs();
        let all = plan(&knobs, None, Setting::default());
        assert_eq!(all[0].name, "defaults");
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a.setting, b.setting, "{} and {}", a.name, b.name);
            }
        }
        let one_at_a_time: usize = knobs.iter().map(|k| k.values.len() - 1).sum();
        let crossed = |a: &str, b: &str| {
            let n = |k: &str| knobs.iter().find(|x| x.name == k).unwrap().values.len() - 1;
            n(a) * n(b)
        };
        let expected = 1
            + one_at_a_time
            + CROSSES.iter().map(|[a, b]| crossed(a, b)).sum::<usize>()
            + PRESETS.len();
        assert_eq!(all.len(), expected);
        assert!(all.iter().any(|e| e.name == "budget=3000 precision=float"));
        assert!(all.iter().any(|e| e.name == "fastest"));

        let only = ["depth".to_string(), "precision".to_string()];
        let few = plan(&knobs, Some(&only), Setting::default());
        let names: Vec<_> = few.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["defaults", "precision=float", "depth=32"]);

        // Defaults with τ off: the knob's `off` is the defaults, its `1` a change.
        let only = ["max-error".to_string()];
        let off = Setting {
            max_error: ErrorBound::Off,
            ..Setting::default()
        };
        let turned = plan(&knobs, Some(&only), off);
        let names: Vec<_> = turned.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "defaults",
                "max-error=0.5",
                "max-error=1",
                "max-error=2",
                "max-error=4"
            ]
        );
        assert_eq!(turned[0].setting, off);
    }
}
