//! `KEY=VALUE` settings applied to a TOML document before it is read into its typed struct, the
//! one way `evsim dataset --set` and `evtrain train --set` change a setting: KEY is a dotted
//! path into the document, VALUE a TOML value (`0.3`, `true`, `[0.3, 0.3]`, `{k = 5}`; a bare
//! word is a string) or `none`, which removes the key (an optional part switched off). The
//! typed read that follows rejects unknown keys and values of the wrong type, so a setting is
//! declared once: in its struct, with its doc. [`field_names`] lists a struct's keys for help
//! texts and errors, from the same declaration.

/// How [`apply_sets`] words its errors for one command.
#[derive(Clone, Copy, Debug)]
pub struct SetWording<'a> {
    /// The flag, e.g. `--set`.
    pub flag: &'a str,
    /// An example of the form, e.g. `events.colour=true or ecrf=none`.
    pub example: &'a str,
    /// What a path that is not in the document means and where to look, e.g. `off in the
    /// preset, or misspelt; see evtrain presets --show NAME`.
    pub missing: &'a str,
    /// Whether a missing table on the path is created (a scene file leaves tables out to take
    /// their defaults) instead of refused (a resolved configuration lists all of its parts).
    pub create_tables: bool,
}

/// Applies `sets` in order to `root`; the error names the setting and what is wrong.
pub fn apply_sets(root: &mut toml::Table, sets: &[String], w: SetWording) -> Result<(), String> {
    for s in sets {
        let flag = w.flag;
        let Some((key, val)) = s.split_once('=') else {
            return Err(format!("{flag} {s}: expected KEY=VALUE, e.g. {}", w.example));
        };
        let key = key.trim();
        let path: Vec<&str> = key.split('.').collect();
        if path.iter().any(|p| p.is_empty()) {
            return Err(format!("{flag} {s}: `{key}` is not a dotted path of names, e.g. {}", w.example));
        }
        let val = val.trim();
        let value = if val == "none" {
            None
        } else {
            let parsed: Option<toml::Value> =
                toml::from_str::<toml::Table>(&format!("v = {val}")).ok().and_then(|t| t.get("v").cloned());
            Some(parsed.unwrap_or_else(|| toml::Value::String(val.to_string())))
        };
        let (last, parents) = path.split_last().expect("split gives at least one part");
        let mut table = &mut *root;
        for (i, part) in parents.iter().enumerate() {
            let here = path[..=i].join(".");
            if w.create_tables && value.is_some() && !table.contains_key(*part) {
                table.insert(part.to_string(), toml::Value::Table(toml::Table::new()));
            }
            table = match table.get_mut(*part) {
                Some(toml::Value::Table(t)) => t,
                Some(_) => return Err(format!("{flag} {s}: `{here}` is a value, not a table")),
                None => return Err(format!("{flag} {s}: `{here}` is not in this configuration ({})", w.missing)),
            };
        }
        match value {
            Some(v) => {
                table.insert(last.to_string(), v);
            }
            None => {
                if table.remove(*last).is_none() {
                    return Err(format!("{flag} {s}: `{key}` is not set, nothing to switch off"));
                }
            }
        }
    }
    Ok(())
}

/// The keys of a struct's TOML table: the field names its `Deserialize` impl asks for (serde's
/// names, renames applied), in declaration order; empty for a type that is not a struct. This is
/// how help texts and errors list a table's keys without a hand-kept copy of them.
pub fn field_names<'de, T: serde::Deserialize<'de>>() -> &'static [&'static str] {
    let mut probe = FieldProbe(&[]);
    let _ = T::deserialize(&mut probe);
    probe.0
}

/// A deserializer that records the field list of `deserialize_struct` and gives no data.
struct FieldProbe(&'static [&'static str]);

impl<'de> serde::Deserializer<'de> for &mut FieldProbe {
    type Error = serde::de::value::Error;

    fn deserialize_any<V: serde::de::Visitor<'de>>(self, _: V) -> Result<V::Value, Self::Error> {
        Err(serde::de::Error::custom("field probe: no data"))
    }

    fn deserialize_struct<V: serde::de::Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, Self::Error> {
        self.0 = fields;
        Err(serde::de::Error::custom("field probe: no data"))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf option
        unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_names_lists_a_structs_keys() {
        #[derive(serde::Deserialize)]
        #[allow(dead_code)]
        struct S {
            a: u32,
            #[serde(rename = "b_renamed")]
            b: f32,
        }
        assert_eq!(field_names::<S>(), ["a", "b_renamed"]);
        assert!(field_names::<u32>().is_empty());
    }

    const W: SetWording = SetWording { flag: "--set", example: "a.b=1", missing: "misspelt?", create_tables: false };

    fn doc() -> toml::Table {
        toml::from_str("x = 1\n[a]\nb = 2\n[a.c]\nd = true\n").unwrap()
    }

    #[test]
    fn sets_values_tables_and_none_and_names_each_mistake() {
        let mut t = doc();
        let sets = ["x=2.5", "a.b=[1, 2]", "a.c={e = 3}", "a.name=word", "a.b=none"].map(String::from);
        apply_sets(&mut t, &sets, W).unwrap();
        assert_eq!(t["x"].as_float(), Some(2.5));
        assert!(!t["a"].as_table().unwrap().contains_key("b"));
        assert_eq!(t["a"]["c"]["e"].as_integer(), Some(3));
        assert_eq!(t["a"]["name"].as_str(), Some("word"));
        for (bad, says) in [
            ("x", "expected KEY=VALUE, e.g. a.b=1"),
            ("a..b=1", "not a dotted path"),
            ("x.y=1", "`x` is a value, not a table"),
            ("q.r=1", "`q` is not in this configuration (misspelt?)"),
            ("a.zz=none", "`a.zz` is not set, nothing to switch off"),
        ] {
            let err = apply_sets(&mut doc(), &[bad.to_string()], W).unwrap_err();
            assert!(err.contains(says) && err.starts_with(&format!("--set {bad}")), "{bad}: {err}");
        }
        // A scene file's tables may be absent: they are created for a value.
        let mut t = doc();
        apply_sets(&mut t, &["q.r.s=1".to_string()], SetWording { create_tables: true, ..W }).unwrap();
        assert_eq!(t["q"]["r"]["s"].as_integer(), Some(1));
        assert!(apply_sets(&mut doc(), &["q.r=none".into()], SetWording { create_tables: true, ..W }).is_err());
    }
}
