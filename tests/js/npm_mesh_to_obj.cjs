// Converts an npm mesh package ({positions, cells}) to a Wavefront OBJ on stdout.
// Usage: node npm_mesh_to_obj.cjs bunny "Stanford bunny, Stanford 3D Scanning Repository"
const name = process.argv[2];
const mesh = require(name);
const out = [];
out.push(`# ${process.argv[3] || name}`);
out.push(`# Converted from the npm package "${name}" (licence: Public Domain).`);
out.push(`o ${name}`);
for (const p of mesh.positions) out.push(`v ${p[0]} ${p[1]} ${p[2]}`);
for (const c of mesh.cells) out.push(`f ${c.map((i) => i + 1).join(' ')}`);
process.stdout.write(out.join('\n') + '\n');
