// One meshoptimizer call for the bench suite's meshopt* rows (methods/meshopt.py).
//
// Request on stdin:  u32 (little-endian) header length, the JSON header, then the buffers
//   indices   index_count      x u32
//   positions vertex_count * 3 x f32
//   attributes vertex_count * attribute_count x f32   (attributes, update, permissive)
//   lock      vertex_count     x u8                    (when header.lock is true)
// Header: {op, index_count, vertex_count, attribute_count, weights, lock,
//          target_index_count, target_error, flags}
//   op: "simplify" | "attributes" | "update" | "sloppy" | "version"
// Reply on stdout: u32 header length, the JSON header {index_count, error, scale, seconds,
// version, node}, then the kept indices (index_count x u32) and, for "update", the
// updated positions and attributes (as laid out in the request).
// Any problem: one line on stderr and exit status 2 (the caller reports that line).

import { readFileSync } from 'node:fs';
import { performance } from 'node:perf_hooks';
import { MeshoptSimplifier } from 'meshoptimizer';

const VERSION = JSON.parse(
	readFileSync(new URL('./node_modules/meshoptimizer/package.json', import.meta.url), 'utf8')
).version;

function fail(message) {
	process.stderr.write(message.replace(/\s+/g, ' ').trim() + '\n');
	process.exit(2);
}

function slice(buffer, offset, bytes, Type, what) {
	if (offset + bytes > buffer.length) {
		fail(`truncated request: ${what} needs ${bytes} bytes, ${Math.max(0, buffer.length - offset)} left`);
	}
	// copy into a fresh, aligned buffer (the library writes back into some of them)
	const copy = new Uint8Array(bytes);
	copy.set(buffer.subarray(offset, offset + bytes));
	return new Type(copy.buffer);
}

function count(header, key) {
	const value = header[key];
	if (!Number.isInteger(value) || value < 0) fail(`header field ${key} must be a whole number >= 0, got ${JSON.stringify(value)}`);
	return value;
}

function parse(input) {
	if (input.length < 4) fail(`truncated request: ${input.length} bytes, no header`);
	const headerBytes = input.readUInt32LE(0);
	if (4 + headerBytes > input.length) fail(`truncated request: header of ${headerBytes} bytes, ${input.length - 4} given`);
	let header;
	try {
		header = JSON.parse(input.subarray(4, 4 + headerBytes).toString('utf8'));
	} catch (err) {
		fail(`request header is not JSON: ${err.message}`);
	}
	if (header.op === 'version') return { header };
	const indexCount = count(header, 'index_count');
	const vertexCount = count(header, 'vertex_count');
	const attributeCount = header.attribute_count === undefined ? 0 : count(header, 'attribute_count');
	if (indexCount % 3 !== 0) fail(`index buffer of ${indexCount} indices is not whole triangles`);
	let offset = 4 + headerBytes;
	const indices = slice(input, offset, indexCount * 4, Uint32Array, 'the index buffer');
	offset += indexCount * 4;
	const positions = slice(input, offset, vertexCount * 12, Float32Array, 'the positions');
	offset += vertexCount * 12;
	let attributes = null;
	if (attributeCount > 0) {
		attributes = slice(input, offset, vertexCount * attributeCount * 4, Float32Array, 'the attributes');
		offset += vertexCount * attributeCount * 4;
	}
	let lock = null;
	if (header.lock) {
		lock = slice(input, offset, vertexCount, Uint8Array, 'the vertex locks');
		offset += vertexCount;
	}
	if (offset !== input.length) fail(`malformed request: ${input.length - offset} bytes beyond the buffers the header declares`);
	for (let i = 0; i < indexCount; ++i) {
		if (indices[i] >= vertexCount) fail(`index ${indices[i]} at position ${i} is out of range for ${vertexCount} vertices`);
	}
	for (let i = 0; i < positions.length; ++i) {
		if (!Number.isFinite(positions[i])) fail(`position component ${i} is not finite (${positions[i]})`);
	}
	return { header, indices, positions, attributes, attributeCount, lock, vertexCount };
}

function run(request) {
	const { header, indices, positions, attributes, attributeCount, lock } = request;
	const target = count(header, 'target_index_count');
	const error = Number(header.target_error);
	const flags = header.flags || [];
	const weights = header.weights || [];
	if (target > indices.length || target % 3 !== 0) fail(`target_index_count ${target} must be a multiple of 3 and at most ${indices.length}`);
	if (!(error >= 0)) fail(`target_error must be >= 0, got ${header.target_error}`);
	if (['attributes', 'update'].includes(header.op) && weights.length !== attributeCount) {
		fail(`${weights.length} attribute weights for ${attributeCount} attributes`);
	}
	const scale = MeshoptSimplifier.getScale(positions, 3);
	const start = performance.now();
	let kept, resultError;
	switch (header.op) {
		case 'simplify':
			[kept, resultError] = MeshoptSimplifier.simplify(indices, positions, 3, target, error, flags);
			break;
		case 'attributes':
			[kept, resultError] = MeshoptSimplifier.simplifyWithAttributes(
				indices, positions, 3, attributes, attributeCount, weights, lock, target, error, flags);
			break;
		case 'update': {
			const [n, e] = MeshoptSimplifier.simplifyWithUpdate(
				indices, positions, 3, attributes, attributeCount, weights, lock, target, error, flags);
			kept = indices.subarray(0, n);
			resultError = e;
			break;
		}
		case 'sloppy':
			[kept, resultError] = MeshoptSimplifier.simplifySloppy(indices, positions, 3, lock, target, error);
			break;
		default:
			fail(`unknown op ${JSON.stringify(header.op)}`);
	}
	const seconds = (performance.now() - start) / 1000;
	const parts = [new Uint8Array(kept.buffer, kept.byteOffset, kept.byteLength)];
	if (header.op === 'update') {
		parts.push(new Uint8Array(positions.buffer), new Uint8Array(attributes.buffer));
	}
	return [{ index_count: kept.length, error: resultError, scale, seconds }, parts];
}

const input = readFileSync(0);
const request = parse(input);
await MeshoptSimplifier.ready;
let reply = { version: VERSION, node: process.version };
let parts = [];
if (request.header.op !== 'version') {
	let result;
	try {
		result = run(request);
	} catch (err) {
		fail(`meshoptimizer ${VERSION}: ${err.message}`);
	}
	reply = { ...result[0], ...reply };
	parts = result[1];
}
const head = Buffer.from(JSON.stringify(reply), 'utf8');
const length = Buffer.alloc(4);
length.writeUInt32LE(head.length, 0);
process.stdout.write(Buffer.concat([length, head, ...parts.map((p) => Buffer.from(p.buffer, p.byteOffset, p.byteLength))]));
