//! The vertices of a COLLADA (`.dae`) collision mesh: treecal's own reader (roxmltree for the
//! XML), replacing `mesh-loader`'s for this format because that one panics or aborts on
//! malformed files (issue 21; see `docs/file-formats.md`, "Collision meshes").
//!
//! The collision checker needs only the vertices (it builds convex hulls), so only those are
//! read: for every `<geometry>` `<mesh>`, the positions its primitives (`<triangles>`,
//! `<polylist>`, `<polygons>`, ...) index through their `VERTEX` input, placed by every
//! `<instance_geometry>` of the visual scene (node `<matrix>`, `<translate>`, `<rotate>`,
//! `<scale>`, and `<instance_node>`), in metres (`<asset><unit meter>`). A geometry no node
//! places counts as is. Every count, index and reference is checked against what the file
//! holds before it is used, and nothing recurses or allocates by a count the file states, so
//! no file makes the reader panic, abort or run out of memory within the size limit.

use crate::limits::{MAX_MESH_VERTICES, MAX_XML_DEPTH, MAX_XML_NODES};
use crate::math::Vec3;
use nalgebra::{Matrix4, Unit, Vector3};
use roxmltree::{Document, Node, NodeId, ParsingOptions};
use std::cell::RefCell;
use std::collections::{BTreeSet, HashMap};
use std::rc::Rc;

type Found<T> = std::result::Result<T, String>;

/// The primitives whose `<p>` lists index the vertices.
const PRIMITIVES: [&str; 7] = [
    "triangles",
    "polylist",
    "polygons",
    "trifans",
    "tristrips",
    "lines",
    "linestrips",
];

/// The vertex positions (m) of every placed geometry of COLLADA `text`, or what is wrong
/// (with its line).
pub(crate) fn collada_vertices(text: &str) -> Found<Vec<Vec3>> {
    // roxmltree's tokenizer recurses per element: the depth is checked on the text first.
    check_text_depth(text)?;
    let options = ParsingOptions {
        allow_dtd: false,
        nodes_limit: MAX_XML_NODES,
    };
    let doc = Document::parse_with_options(text, options).map_err(|e| match e {
        roxmltree::Error::NodesLimitReached => format!(
            "the XML has more than {MAX_XML_NODES} nodes (docs/file-formats.md, \"Limits\")"
        ),
        other => format!("not well-formed XML: {other}"),
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "COLLADA" {
        return Err(format!(
            "the root element is <{}>, not <COLLADA>",
            root.tag_name().name()
        ));
    }
    let reader = Reader::new(&doc);
    let unit = reader.unit(root)?;
    let mut placements: HashMap<&str, Vec<Matrix4<f64>>> = HashMap::new();
    for (id, transform) in reader.placements(root)? {
        placements.entry(id).or_default().push(transform);
    }
    let identity = [Matrix4::identity()];
    let mut vertices = Vec::new();
    for geometry in root.descendants().filter(|n| n.has_tag_name("geometry")) {
        let local = reader.geometry_vertices(geometry)?;
        let transforms = match geometry.attribute("id").and_then(|id| placements.get(id)) {
            Some(transforms) => transforms.as_slice(),
            None => &identity,
        };
        for transform in transforms {
            if vertices.len() + local.len() > MAX_MESH_VERTICES {
                return Err(format!(
                    "the file places more than {MAX_MESH_VERTICES} vertices \
                     (docs/file-formats.md, \"Limits\")"
                ));
            }
            vertices.extend(
                local
                    .iter()
                    .map(|v| unit * transform.transform_point(&(*v).into()).coords),
            );
        }
    }
    Ok(vertices)
}

/// Fails if elements nest deeper than [`MAX_XML_DEPTH`] (no real mesh nests more than a few
/// dozen levels), from the text alone: start tags open a level, end tags and `/>` close one;
/// comments, CDATA, processing instructions, declarations and quoted attribute values are
/// skipped. Malformed XML may be counted too deep, never too shallow for the parser.
fn check_text_depth(text: &str) -> Found<()> {
    let bytes = text.as_bytes();
    let skip_to = |from: usize, end: &str| {
        text[from..]
            .find(end)
            .map_or(bytes.len(), |at| from + at + end.len())
    };
    let mut depth = 0usize;
    let mut i = 0;
    while let Some(at) = text[i..].find('<') {
        i += at;
        let rest = &text[i..];
        if rest.starts_with("<!--") {
            i = skip_to(i, "-->");
        } else if rest.starts_with("<![CDATA[") {
            i = skip_to(i, "]]>");
        } else if rest.starts_with("<?") {
            i = skip_to(i, "?>");
        } else if rest.starts_with("</") {
            depth = depth.saturating_sub(1);
            i = skip_to(i, ">");
        } else if rest.starts_with("<!") {
            i = skip_to(i, ">");
        } else {
            // A start tag: find its end outside quoted attribute values.
            let mut quote = None;
            let mut j = i + 1;
            while j < bytes.len() {
                match (quote, bytes[j]) {
                    (Some(q), b) if b == q => quote = None,
                    (Some(_), _) => {}
                    (None, b'"' | b'\'') => quote = Some(bytes[j]),
                    (None, b'>') => break,
                    _ => {}
                }
                j += 1;
            }
            if bytes[j - 1] != b'/' {
                depth += 1;
                if depth > MAX_XML_DEPTH {
                    let line = text[..i].matches('\n').count() + 1;
                    return Err(format!(
                        "line {line}: the elements nest more than {MAX_XML_DEPTH} levels deep \
                         (docs/file-formats.md, \"Limits\")"
                    ));
                }
            }
            i = j + 1;
        }
        if i >= bytes.len() {
            break;
        }
    }
    Ok(())
}

/// "line N" of a node.
fn line(node: Node) -> String {
    format!(
        "line {}",
        node.document().text_pos_at(node.range().start).row
    )
}

/// The element an `#id` reference names.
struct Reader<'a, 'input> {
    ids: HashMap<&'a str, Node<'a, 'input>>,
    /// The points of each `<source>` read so far (a source can serve many primitives).
    sources: RefCell<HashMap<NodeId, Rc<Vec<Vec3>>>>,
}

impl<'a, 'input> Reader<'a, 'input> {
    fn new(doc: &'a Document<'input>) -> Self {
        let ids = doc
            .descendants()
            .filter_map(|n| Some((n.attribute("id")?, n)))
            .collect();
        Reader {
            ids,
            sources: RefCell::new(HashMap::new()),
        }
    }

    /// The element `node`'s attribute `name` (`#id`) refers to.
    fn target(&self, node: Node<'a, 'input>, name: &str) -> Found<Node<'a, 'input>> {
        let reference = node.attribute(name).ok_or_else(|| {
            format!(
                "{}: <{}> has no {name} attribute",
                line(node),
                node.tag_name().name()
            )
        })?;
        reference
            .strip_prefix('#')
            .and_then(|id| self.ids.get(id).copied())
            .ok_or_else(|| {
                format!(
                    "{}: <{}> {name}=\"{}\" names no element of the file",
                    line(node),
                    node.tag_name().name(),
                    crate::limits::cut(reference)
                )
            })
    }

    /// Metres per unit: `<asset><unit meter>` of the root, 1 if not given.
    fn unit(&self, root: Node) -> Found<f64> {
        let unit = root
            .children()
            .filter(|n| n.has_tag_name("asset"))
            .flat_map(|a| a.children())
            .find(|n| n.has_tag_name("unit"));
        let Some(unit) = unit else { return Ok(1.0) };
        let Some(meter) = unit.attribute("meter") else {
            return Ok(1.0);
        };
        match meter.trim().parse::<f64>() {
            Ok(value) if value.is_finite() && value > 0.0 && value <= crate::limits::MAX_FACTOR => {
                Ok(value)
            }
            _ => Err(format!(
                "{}: <unit meter=\"{}\"> is not a positive number up to {}",
                line(unit),
                crate::limits::cut(meter),
                crate::limits::MAX_FACTOR
            )),
        }
    }

    /// Each `<instance_geometry>` of the visual scene: the geometry id and its transform.
    fn placements(&self, root: Node<'a, 'input>) -> Found<Vec<(&'a str, Matrix4<f64>)>> {
        let scene = root
            .children()
            .filter(|n| n.has_tag_name("scene"))
            .flat_map(|s| s.children())
            .find(|n| n.has_tag_name("instance_visual_scene"));
        let visual = match scene {
            Some(instance) => Some(self.target(instance, "url")?),
            None => root.descendants().find(|n| n.has_tag_name("visual_scene")),
        };
        let Some(visual) = visual else {
            return Ok(Vec::new());
        };
        let mut placements = Vec::new();
        let mut stack = vec![(visual, Matrix4::identity(), 0usize)];
        let mut visits = 0usize;
        while let Some((node, parent, depth)) = stack.pop() {
            visits += 1;
            if depth > MAX_XML_DEPTH || visits > MAX_XML_NODES as usize {
                return Err(format!(
                    "{}: the <instance_node> references nest too deep or loop",
                    line(node)
                ));
            }
            let mut transform = parent;
            for child in node.children().filter(Node::is_element) {
                match child.tag_name().name() {
                    "matrix" | "translate" | "rotate" | "scale" => {
                        transform *= local_transform(child)?;
                    }
                    "lookat" | "skew" => {
                        return Err(format!(
                            "{}: <{}> transforms are not supported; bake them into the mesh",
                            line(child),
                            child.tag_name().name()
                        ))
                    }
                    "instance_geometry" => {
                        let geometry = self.target(child, "url")?;
                        let id = geometry.attribute("id").unwrap_or("");
                        placements.push((id, transform));
                    }
                    "node" => stack.push((child, transform, depth + 1)),
                    "instance_node" => {
                        stack.push((self.target(child, "url")?, transform, depth + 1))
                    }
                    _ => {}
                }
            }
        }
        Ok(placements)
    }

    /// The positions a geometry's primitives index (each once), in the file's unit.
    fn geometry_vertices(&self, geometry: Node<'a, 'input>) -> Found<Vec<Vec3>> {
        let mut used: HashMap<NodeId, (Rc<Vec<Vec3>>, BTreeSet<usize>)> = HashMap::new();
        for mesh in geometry.children().filter(|n| n.has_tag_name("mesh")) {
            for primitive in mesh
                .children()
                .filter(|n| PRIMITIVES.contains(&n.tag_name().name()))
            {
                self.primitive_vertices(primitive, &mut used)?;
            }
        }
        Ok(used
            .values()
            .flat_map(|(points, indices)| indices.iter().map(|&i| points[i]))
            .collect())
    }

    /// Adds the indices of a primitive's `<p>` lists to `used`, by positions source.
    fn primitive_vertices(
        &self,
        primitive: Node<'a, 'input>,
        used: &mut HashMap<NodeId, (Rc<Vec<Vec3>>, BTreeSet<usize>)>,
    ) -> Found<()> {
        let name = primitive.tag_name().name();
        let at = line(primitive);
        let inputs: Vec<Node> = primitive
            .children()
            .filter(|n| n.has_tag_name("input"))
            .collect();
        if inputs.is_empty() {
            return Err(format!(
                "{at}: <{name}> has no <input>; it needs one with semantic=\"VERTEX\""
            ));
        }
        let mut stride = 0usize;
        let mut vertex = None;
        for input in &inputs {
            let offset = count_attribute(*input, "offset", 0)?;
            if offset >= MAX_INPUTS {
                return Err(format!(
                    "{}: <input offset=\"{offset}\"> is beyond {MAX_INPUTS}",
                    line(*input)
                ));
            }
            stride = stride.max(offset + 1);
            if input.attribute("semantic") == Some("VERTEX") {
                vertex = Some((*input, offset));
            }
        }
        let Some((input, offset)) = vertex else {
            return Err(format!("{at}: <{name}> has no <input semantic=\"VERTEX\">"));
        };
        let vertices = self.target(input, "source")?;
        let position = vertices
            .children()
            .find(|n| n.has_tag_name("input") && n.attribute("semantic") == Some("POSITION"))
            .ok_or_else(|| {
                format!(
                    "{}: <{}> has no <input semantic=\"POSITION\">",
                    line(vertices),
                    vertices.tag_name().name()
                )
            })?;
        let source = self.target(position, "source")?;
        let positions = self.positions(source)?;
        let (_, indices) = used
            .entry(source.id())
            .or_insert_with(|| (positions.clone(), BTreeSet::new()));
        let lists = primitive
            .descendants()
            .filter(|n| n.has_tag_name("p") && !n.ancestors().any(|a| a.has_tag_name("h")));
        for list in lists {
            let tokens = list.text().unwrap_or("").split_ascii_whitespace();
            for (k, token) in tokens.enumerate() {
                let index: usize = token.parse().map_err(|_| {
                    format!(
                        "{}: '{}' in <p> is not an index (a whole number ≥ 0)",
                        line(list),
                        crate::limits::cut(token)
                    )
                })?;
                if k % stride != offset {
                    continue;
                }
                if index >= positions.len() {
                    return Err(format!(
                        "{}: <p> of <{name}> indexes vertex {index}, but its positions source \
                         holds {} (0 to {})",
                        line(list),
                        positions.len(),
                        positions.len().saturating_sub(1)
                    ));
                }
                indices.insert(index);
            }
        }
        Ok(())
    }

    /// The points of a `<source>`: its accessor's `count` points of `stride` values from
    /// `offset`, the first three of each, checked against the array's length.
    fn positions(&self, source: Node<'a, 'input>) -> Found<Rc<Vec<Vec3>>> {
        if let Some(points) = self.sources.borrow().get(&source.id()) {
            return Ok(points.clone());
        }
        let accessor = source
            .children()
            .filter(|n| n.has_tag_name("technique_common"))
            .flat_map(|t| t.children())
            .find(|n| n.has_tag_name("accessor"))
            .ok_or_else(|| {
                format!(
                    "{}: <{}> has no <technique_common><accessor>",
                    line(source),
                    source.tag_name().name()
                )
            })?;
        let count = count_attribute(accessor, "count", usize::MAX)?;
        let stride = count_attribute(accessor, "stride", 1)?;
        let offset = count_attribute(accessor, "offset", 0)?;
        let array = self.target(accessor, "source")?;
        if stride < 3 {
            return Err(format!(
                "{}: <accessor stride=\"{stride}\"> of positions needs at least 3 (x, y, z)",
                line(accessor)
            ));
        }
        let values = float_values(array)?;
        let needed = count
            .checked_mul(stride)
            .and_then(|n| n.checked_add(offset));
        if needed.is_none_or(|n| n > values.len()) {
            return Err(format!(
                "{}: <accessor count=\"{count}\" stride=\"{stride}\" offset=\"{offset}\"> \
                 needs more values than the {} its array (line {}) holds",
                line(accessor),
                values.len(),
                array.document().text_pos_at(array.range().start).row
            ));
        }
        let points: Rc<Vec<Vec3>> = Rc::new(
            (0..count)
                .map(|i| {
                    let start = offset + i * stride;
                    Vec3::new(values[start], values[start + 1], values[start + 2])
                })
                .collect(),
        );
        self.sources
            .borrow_mut()
            .insert(source.id(), points.clone());
        Ok(points)
    }
}

/// Most inputs of one primitive (their `offset`s): real files have up to 5.
const MAX_INPUTS: usize = 64;

/// A non-negative whole-number attribute, `default` if absent (`usize::MAX`: required).
fn count_attribute(node: Node, name: &str, default: usize) -> Found<usize> {
    match node.attribute(name) {
        None if default == usize::MAX => Err(format!(
            "{}: <{}> has no {name} attribute",
            line(node),
            node.tag_name().name()
        )),
        None => Ok(default),
        Some(text) => text.trim().parse().map_err(|_| {
            format!(
                "{}: <{} {name}=\"{}\"> is not a whole number ≥ 0",
                line(node),
                node.tag_name().name(),
                crate::limits::cut(text)
            )
        }),
    }
}

/// The numbers of a `<float_array>` (decimal commas read as points, as some exporters write).
fn float_values(array: Node) -> Found<Vec<f64>> {
    if !array.has_tag_name("float_array") {
        return Err(format!(
            "{}: positions must come from a <float_array>, not <{}>",
            line(array),
            array.tag_name().name()
        ));
    }
    array
        .text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .map(|token| {
            token
                .parse::<f64>()
                .or_else(|_| token.replace(',', ".").parse())
                .map_err(|_| {
                    format!(
                        "{}: '{}' in <float_array> is not a number",
                        line(array),
                        crate::limits::cut(token)
                    )
                })
        })
        .collect()
}

/// The transform of a `<matrix>`, `<translate>`, `<rotate>` (axis, degrees) or `<scale>`.
fn local_transform(node: Node) -> Found<Matrix4<f64>> {
    let name = node.tag_name().name();
    let values = float_values_of(node)?;
    let expected = match name {
        "matrix" => 16,
        "rotate" => 4,
        _ => 3,
    };
    if values.len() != expected {
        return Err(format!(
            "{}: <{name}> holds {} numbers; it needs {expected}",
            line(node),
            values.len()
        ));
    }
    let v = Vector3::new(values[0], values[1], values[2]);
    Ok(match name {
        "matrix" => Matrix4::from_row_slice(&values),
        "translate" => Matrix4::new_translation(&v),
        "scale" => Matrix4::new_nonuniform_scaling(&v),
        _ => match Unit::try_new(v, 1e-12) {
            Some(axis) => Matrix4::from_axis_angle(&axis, values[3].to_radians()),
            None => Matrix4::identity(),
        },
    })
}

fn float_values_of(node: Node) -> Found<Vec<f64>> {
    node.text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .take(17)
        .map(|token| {
            token
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    format!(
                        "{}: '{}' in <{}> is not a finite number",
                        line(node),
                        crate::limits::cut(token),
                        node.tag_name().name()
                    )
                })
        })
        .collect()
}
