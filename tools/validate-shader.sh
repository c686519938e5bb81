#!/usr/bin/env bash
# Validates one GLSL file with glslangValidator, as it is embedded: its #include lines expanded
# by tools/embed_shaders.c --expand (EMBED: that tool, build/embed-shaders by default). The files
# have no #version line (the runtime prepends it), so the same prefix is added here.
set -eu
f=$1
embed=${EMBED:-build/embed-shaders}
stage=${f##*.}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
{ echo "#version 430 core"; "$embed" --expand "$f"; } > "$tmp/shader.$stage"
if ! out=$(glslangValidator -S "$stage" "$tmp/shader.$stage" 2>&1); then
  echo "$f: glslangValidator failed:"; echo "$out" | sed "s#$tmp/shader.$stage#$f#"; exit 1
fi
