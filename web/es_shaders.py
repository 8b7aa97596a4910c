#!/usr/bin/env python3
"""The page's shaders, made from meshview's (docs/BROWSER.md, "Drawing"):
`es_shaders.py OUT.js DIR` reads DIR/cell.vert.glsl, DIR/cell.frag.glsl and
DIR/apo.glsl (client/view/shaders, the one source of truth) and writes OUT.js,
which defines `MsShaders` with the GLSL ES 3.00 variant of each, for WebGL 2.

The law is not rewritten: the variant is the native text with the few changes
GLSL ES 3.00 needs, each a substitution that must match exactly as often as
stated (a change of the native text that breaks one stops the build):
- `#version 410 core` becomes `#version 300 es` with a marker line where the
  page inserts the program's #defines and the precision statements;
- positions arrive in world units, one buffer for the whole cut (no cell-local
  copy): `cell_position` is a macro taking them into the cell's cube
  (`cell_cube`: origin and side), so the rest of the vertex stage and every
  use of v_cell is the native one;
- ES has no gl_ClipDistance: the vertex stage never gets MS_SECTIONS (its
  block writes clip distances), and the fragment stage discards what the
  planes cut away, with the native planes in the cell's frame
  (`section_plane`, the vertex stage's uniform moved here), first in main();
- ES 3.00 has no bitCount (ES 3.10 has): ms_bit_count, the same count;
- ES has no buffer textures: the APO words lie in a 2D integer texture
  (R32UI) 2^MS_APO_ROW_BITS words wide, read by apo_word(i) where the native
  reads texelFetch(apo_words, i).r.
Everything else (the modes, the light loop, the APO traversal) is the native
text, character for character."""
import json
import os
import sys

MARKER = "// @MS_ES_DEFINES@"


def replace(text, old, new, count, what):
    found = text.count(old)
    if found != count:
        raise SystemExit("es_shaders.py: %s: %r found %d times, expected %d (has the native shader changed?)"
                         % (what, old, found, count))
    return text.replace(old, new)


def version_line(text, what):
    return replace(text, "#version 410 core\n", "#version 300 es\n" + MARKER + "\n", 1, what)


def vertex(text):
    text = version_line(text, "cell.vert.glsl")
    text = replace(text, "layout(location = 0) in vec3 cell_position;",
                   "layout(location = 0) in vec3 world_position;\n"
                   "uniform vec4 cell_cube; // the cell's cube: origin x y z, side\n"
                   "#define cell_position ((world_position - cell_cube.xyz) / cell_cube.w)",
                   1, "cell.vert.glsl")
    return text


def fragment(text):
    text = version_line(text, "cell.frag.glsl")
    text = replace(text, "uniform int section_count;",
                   "uniform int section_count;\n"
                   "uniform vec4 section_plane[3]; // kept where dot(xyz, cell position) + w >= 0",
                   1, "cell.frag.glsl")
    text = replace(text, "void main()\n{\n",
                   "void main()\n{\n"
                   "#ifdef MS_SECTIONS\n"
                   "    for (int k = 0; k < 3; ++k)\n"
                   "        if (k < section_count && dot(section_plane[k].xyz, FRAG_CELL) + section_plane[k].w < 0.0)\n"
                   "            discard;\n"
                   "#endif\n",
                   1, "cell.frag.glsl")
    return text


def apo(text):
    text = replace(text, "uniform usamplerBuffer apo_words;",
                   "uniform highp usampler2D apo_words;\n"
                   "#define MS_APO_ROW_BITS 11\n"
                   "uint apo_word(int i)\n"
                   "{\n"
                   "    return texelFetch(apo_words, ivec2(i & ((1 << MS_APO_ROW_BITS) - 1), i >> MS_APO_ROW_BITS), 0).r;\n"
                   "}\n"
                   "int ms_bit_count(uint v)\n"
                   "{\n"
                   "    v = v - ((v >> 1) & 0x55555555u);\n"
                   "    v = (v & 0x33333333u) + ((v >> 2) & 0x33333333u);\n"
                   "    return int((((v + (v >> 4)) & 0x0F0F0F0Fu) * 0x01010101u) >> 24);\n"
                   "}",
                   1, "apo.glsl")
    for old, count in (("texelFetch(apo_words, word).r", 1), ("texelFetch(apo_words, word + 1).r", 1),
                       ("texelFetch(apo_words, internal ? word + 1 : word).r", 1)):
        inner = old[len("texelFetch(apo_words, "):-len(").r")]
        text = replace(text, old, "apo_word(" + inner + ")", count, "apo.glsl")
    if "texelFetch(apo_words," in text.replace("texelFetch(apo_words, ivec2", ""):
        raise SystemExit("es_shaders.py: apo.glsl: a texelFetch of apo_words not ported")
    text = replace(text, "bitCount(", "ms_bit_count(", 3, "apo.glsl")
    return text


def main():
    if len(sys.argv) != 3:
        sys.stderr.write("usage: es_shaders.py OUT.js SHADER_DIR\n")
        return 2
    out, folder = sys.argv[1], sys.argv[2]

    def read(name):
        with open(os.path.join(folder, name), encoding="utf-8") as f:
            return f.read()

    shaders = {"vertex": vertex(read("cell.vert.glsl")), "fragment": fragment(read("cell.frag.glsl")),
               "apo": apo(read("apo.glsl")), "marker": MARKER}
    for key, text in shaders.items():
        if any(ord(c) > 126 for c in text):
            raise SystemExit("es_shaders.py: %s: a character outside ASCII (GLSL ES wants ASCII)" % key)
    body = ["// Generated by web/es_shaders.py from client/view/shaders (cell.vert.glsl,",
            "// cell.frag.glsl, apo.glsl): meshview's shaders in GLSL ES 3.00. Do not edit.",
            "'use strict';",
            "const MsShaders = " + json.dumps(shaders, indent=1) + ";", ""]
    tmp = out + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write("\n".join(body))
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
