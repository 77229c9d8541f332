//! MoveIt's SRDF: planning groups, named states, end effectors, virtual and passive joints and
//! the pairs of links never checked against each other (`disable_collisions`).
//!
//! Parsing keeps the file's words; [`Srdf::group_joints`] resolves a group (chains, joints,
//! links, subgroups) against the URDF's tree. Writing ([`Srdf::write_disabled`]) produces a
//! file MoveIt reads.

/// One `<group>`: its members as written.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Group {
    /// Group name.
    pub name: String,
    /// `<chain base_link tip_link>` elements.
    pub chains: Vec<(String, String)>,
    /// `<joint name>` elements.
    pub joints: Vec<String>,
    /// `<link name>` elements.
    pub links: Vec<String>,
    /// `<group name>` subgroups.
    pub subgroups: Vec<String>,
}

/// One `<group_state>`: a named configuration of a group.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupState {
    /// State name (`home`, `ready`, ...).
    pub name: String,
    /// The group it configures.
    pub group: String,
    /// Joint values as written.
    pub values: Vec<(String, f64)>,
}

/// One `<end_effector>`.
#[derive(Debug, Clone, PartialEq)]
pub struct EndEffector {
    /// End-effector name.
    pub name: String,
    /// The link it is attached to.
    pub parent_link: String,
    /// The group of its links.
    pub group: String,
    /// The group it belongs to, when given.
    pub parent_group: Option<String>,
}

/// One `<virtual_joint>`: how the robot's root attaches to the world.
#[derive(Debug, Clone, PartialEq)]
pub struct VirtualJoint {
    /// Joint name.
    pub name: String,
    /// `fixed`, `planar` or `floating`.
    pub kind: String,
    /// World frame name.
    pub parent_frame: String,
    /// The robot link it holds (the URDF root).
    pub child_link: String,
}

/// A parsed SRDF.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Srdf {
    /// Robot name.
    pub name: String,
    /// Planning groups.
    pub groups: Vec<Group>,
    /// Named states.
    pub states: Vec<GroupState>,
    /// End effectors.
    pub end_effectors: Vec<EndEffector>,
    /// Virtual joints.
    pub virtual_joints: Vec<VirtualJoint>,
    /// Passive joints (never planned).
    pub passive_joints: Vec<String>,
    /// Link pairs never checked against each other, with MoveIt's reason.
    pub disabled: Vec<(String, String, String)>,
    /// Elements read past, as MoveIt does (e.g. unknown group members).
    pub warnings: Vec<String>,
}

impl Srdf {
    /// Parses SRDF text; errors name the element at fault (the caller adds the file).
    pub fn parse(text: &str) -> Result<Srdf, String> {
        let doc = roxmltree::Document::parse(text).map_err(|e| format!("not valid XML: {e}"))?;
        let root = doc.root_element();
        if root.tag_name().name() != "robot" {
            return Err(format!(
                "root element is <{}>, expected <robot>",
                root.tag_name().name()
            ));
        }
        let attr = |n: roxmltree::Node, key: &str| -> Result<String, String> {
            n.attribute(key).map(str::to_string).ok_or_else(|| {
                format!(
                    "<{}> at line {} has no '{key}' attribute",
                    n.tag_name().name(),
                    doc.text_pos_at(n.range().start).row
                )
            })
        };
        let mut srdf = Srdf {
            name: root.attribute("name").unwrap_or_default().to_string(),
            ..Default::default()
        };
        for n in root.children().filter(|n| n.is_element()) {
            match n.tag_name().name() {
                "group" => {
                    let mut g = Group {
                        name: attr(n, "name")?,
                        ..Default::default()
                    };
                    for m in n.children().filter(|m| m.is_element()) {
                        match m.tag_name().name() {
                            "chain" => g.chains.push((attr(m, "base_link")?, attr(m, "tip_link")?)),
                            "joint" => g.joints.push(attr(m, "name")?),
                            "link" => g.links.push(attr(m, "name")?),
                            "group" => g.subgroups.push(attr(m, "name")?),
                            other => srdf.warnings.push(format!(
                                "group '{}': member <{other}> ignored, as MoveIt ignores it",
                                g.name
                            )),
                        }
                    }
                    srdf.groups.push(g);
                }
                "group_state" => {
                    let name = attr(n, "name")?;
                    let mut values = Vec::new();
                    for m in n.children().filter(|m| m.is_element()) {
                        let joint = attr(m, "name")?;
                        let text = attr(m, "value")?;
                        let first = text.split_whitespace().next().unwrap_or("");
                        let v: f64 = first.parse().map_err(|_| {
                            format!("group_state '{name}': joint '{joint}' has value '{text}', not a number")
                        })?;
                        values.push((joint, v));
                    }
                    srdf.states.push(GroupState {
                        name,
                        group: attr(n, "group")?,
                        values,
                    });
                }
                "end_effector" => srdf.end_effectors.push(EndEffector {
                    name: attr(n, "name")?,
                    parent_link: attr(n, "parent_link")?,
                    group: attr(n, "group")?,
                    parent_group: n.attribute("parent_group").map(str::to_string),
                }),
                "virtual_joint" => srdf.virtual_joints.push(VirtualJoint {
                    name: attr(n, "name")?,
                    kind: attr(n, "type")?,
                    parent_frame: attr(n, "parent_frame")?,
                    child_link: attr(n, "child_link")?,
                }),
                "passive_joint" => srdf.passive_joints.push(attr(n, "name")?),
                "disable_collisions" => srdf.disabled.push((
                    attr(n, "link1")?,
                    attr(n, "link2")?,
                    n.attribute("reason").unwrap_or("").to_string(),
                )),
                // Elements MoveIt also reads that do not change planning here.
                "disable_default_collisions"
                | "enable_collisions"
                | "link_sphere_approximation"
                | "joint_property" => {}
                _ => {}
            }
        }
        Ok(srdf)
    }

    /// The group named `name`.
    pub fn group(&self, name: &str) -> Option<&Group> {
        self.groups.iter().find(|g| g.name == name)
    }

    /// The group planned by default: `arm_with_torso` when present, else the only group with a
    /// chain (else the only one with joints); an error lists the candidates when there are
    /// several.
    pub fn default_group(&self) -> Result<&Group, String> {
        if let Some(g) = self.group("arm_with_torso") {
            return Ok(g);
        }
        let chains: Vec<&Group> = self
            .groups
            .iter()
            .filter(|g| !g.chains.is_empty())
            .collect();
        let candidates = if chains.is_empty() {
            self.groups
                .iter()
                .filter(|g| !g.joints.is_empty())
                .collect()
        } else {
            chains
        };
        match candidates.as_slice() {
            [g] => Ok(g),
            [] => Err("has no group with a chain or joints to plan for".into()),
            many => Err(format!(
                "has several groups ({}); choose one with --group",
                many.iter()
                    .map(|g| g.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
        }
    }

    /// An SRDF holding `disabled` as `disable_collisions` (what `ember robot check
    /// --write-srdf` saves), keeping this file's other elements.
    pub fn write_disabled(
        &self,
        robot_name: &str,
        disabled: &[(String, String, String)],
    ) -> String {
        let mut out = String::from("<?xml version=\"1.0\" ?>\n");
        out += &format!("<robot name=\"{}\">\n", xml_escape(robot_name));
        for g in &self.groups {
            out += &format!("    <group name=\"{}\">\n", xml_escape(&g.name));
            for (b, t) in &g.chains {
                out += &format!(
                    "        <chain base_link=\"{}\" tip_link=\"{}\" />\n",
                    xml_escape(b),
                    xml_escape(t)
                );
            }
            for j in &g.joints {
                out += &format!("        <joint name=\"{}\" />\n", xml_escape(j));
            }
            for l in &g.links {
                out += &format!("        <link name=\"{}\" />\n", xml_escape(l));
            }
            for s in &g.subgroups {
                out += &format!("        <group name=\"{}\" />\n", xml_escape(s));
            }
            out += "    </group>\n";
        }
        for s in &self.states {
            out += &format!(
                "    <group_state name=\"{}\" group=\"{}\">\n",
                xml_escape(&s.name),
                xml_escape(&s.group)
            );
            for (j, v) in &s.values {
                out += &format!(
                    "        <joint name=\"{}\" value=\"{v}\" />\n",
                    xml_escape(j)
                );
            }
            out += "    </group_state>\n";
        }
        for e in &self.end_effectors {
            out += &format!(
                "    <end_effector name=\"{}\" parent_link=\"{}\" group=\"{}\"{} />\n",
                xml_escape(&e.name),
                xml_escape(&e.parent_link),
                xml_escape(&e.group),
                e.parent_group
                    .as_ref()
                    .map(|p| format!(" parent_group=\"{}\"", xml_escape(p)))
                    .unwrap_or_default()
            );
        }
        for v in &self.virtual_joints {
            out += &format!(
                "    <virtual_joint name=\"{}\" type=\"{}\" parent_frame=\"{}\" child_link=\"{}\" />\n",
                xml_escape(&v.name),
                xml_escape(&v.kind),
                xml_escape(&v.parent_frame),
                xml_escape(&v.child_link)
            );
        }
        for p in &self.passive_joints {
            out += &format!("    <passive_joint name=\"{}\" />\n", xml_escape(p));
        }
        for (a, b, reason) in disabled {
            out += &format!(
                "    <disable_collisions link1=\"{}\" link2=\"{}\" reason=\"{}\" />\n",
                xml_escape(a),
                xml_escape(b),
                xml_escape(reason)
            );
        }
        out += "</robot>\n";
        out
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = r#"<?xml version="1.0"?>
<robot name="arm">
  <virtual_joint name="world_joint" type="fixed" parent_frame="world" child_link="base"/>
  <group name="manipulator"><chain base_link="base" tip_link="tool"/></group>
  <group name="hand"><link name="finger"/><joint name="finger_joint"/></group>
  <group name="all"><group name="manipulator"/><group name="hand"/></group>
  <group_state name="home" group="manipulator"><joint name="j1" value="0.5"/></group_state>
  <end_effector name="eef" parent_link="tool" group="hand" parent_group="manipulator"/>
  <passive_joint name="caster"/>
  <disable_collisions link1="base" link2="l1" reason="Adjacent"/>
</robot>"#;

    #[test]
    fn every_element_is_read() {
        let sut = Srdf::parse(TEXT).unwrap();
        assert_eq!(sut.name, "arm");
        assert_eq!(sut.groups.len(), 3);
        assert_eq!(sut.group("manipulator").unwrap().chains[0].1, "tool");
        assert_eq!(sut.group("all").unwrap().subgroups.len(), 2);
        assert_eq!(sut.states[0].values, vec![("j1".to_string(), 0.5)]);
        assert_eq!(sut.end_effectors[0].parent_link, "tool");
        assert_eq!(sut.virtual_joints[0].child_link, "base");
        assert_eq!(sut.passive_joints, vec!["caster".to_string()]);
        assert_eq!(sut.disabled[0].2, "Adjacent");
    }

    #[test]
    fn default_group_is_the_only_chain() {
        let sut = Srdf::parse(TEXT).unwrap();
        assert_eq!(sut.default_group().unwrap().name, "manipulator");
        let two = TEXT.replace(
            "<group name=\"hand\">",
            "<group name=\"other\"><chain base_link=\"base\" tip_link=\"l1\"/></group><group name=\"hand\">",
        );
        let err = Srdf::parse(&two).unwrap().default_group().unwrap_err();
        assert!(
            err.contains("manipulator") && err.contains("--group"),
            "{err}"
        );
    }

    #[test]
    fn written_file_parses_back() {
        let sut = Srdf::parse(TEXT).unwrap();
        let disabled = vec![("a".to_string(), "b".to_string(), "Never".to_string())];
        let back = Srdf::parse(&sut.write_disabled("arm", &disabled)).unwrap();
        assert_eq!(back.groups, sut.groups);
        assert_eq!(back.disabled, disabled);
        assert_eq!(back.states, sut.states);
    }

    #[test]
    fn missing_attribute_is_named() {
        let err = Srdf::parse("<robot><group/></robot>").unwrap_err();
        assert!(err.contains("'name'"), "{err}");
        assert!(Srdf::parse("<robot").unwrap_err().contains("XML"));
    }
}
