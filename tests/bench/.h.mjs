import fs from 'fs';
import { MeshoptEncoder as E } from 'meshoptimizer';
await E.ready;
const glb = fs.readFileSync(process.argv[2]);
const jl = glb.readUInt32LE(12);
const doc = JSON.parse(glb.subarray(20, 20 + jl).toString());
const bin = glb.subarray(20 + jl + 8);
const one = (name) => { const v = doc.bufferViews.filter((v) => v.name === name)[0]; return Uint8Array.from(bin.subarray(v.byteOffset||0, (v.byteOffset||0)+v.byteLength)).buffer; };
const ext = new Int16Array(one('extrusion'));
const nv = ext.length/4;
const u8 = (a) => new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
const vb = (a) => E.encodeVertexBufferLevel(u8(a), nv, 8, 2, 0).length;
const L = new Float64Array(nv); let H=0;
for (let k=0;k<nv;k++){L[k]=Math.hypot(ext[4*k],ext[4*k+1],ext[4*k+2]); H=Math.max(H,L[k]);}
const sorted=Float64Array.from(L).sort(); console.log('H',H,'median',sorted[nv>>1], 'p40', sorted[Math.floor(nv*0.4)]);
console.log('as written', vb(ext));
const make=(hf)=>{const o=new Int16Array(4*nv); for(let k=0;k<nv;k++){const h=hf(L[k],k); for(let c=0;c<3;c++) o[4*k+c]=L[k]>0?Math.round(ext[4*k+c]/L[k]*h):0;} return o;};
console.log('uniform H', vb(make(()=>H)));
console.log('uniform median', vb(make(()=>sorted[nv>>1])));
for (const n of [2,4,8,16]) console.log('levels',n, vb(make((l)=>Math.max(1,Math.floor(l/(H/n)))*(H/n))));
const idx = new Uint32Array(one('indices'));
const pos = new Int16Array(one('position'));
// weld by position
const key=new Map(); const rep=new Int32Array(nv);
for(let k=0;k<nv;k++){const s=pos[4*k]+','+pos[4*k+1]+','+pos[4*k+2]; if(!key.has(s)) key.set(s,k); rep[k]=key.get(s);}
const nb=Array.from({length:nv},()=>[]);
for(let t=0;t<idx.length;t+=3) for(let i=0;i<3;i++){const a=rep[idx[t+i]],b=rep[idx[t+(i+1)%3]]; nb[a].push(b); nb[b].push(a);}
let d=new Float64Array(3*nv); for(let k=0;k<nv;k++) for(let c=0;c<3;c++) d[3*k+c]=L[k]>0?ext[4*k+c]/L[k]:0;
for (const rounds of [5,20,100]) {
  let cur=Float64Array.from(d);
  for(let r=0;r<rounds;r++){const nx=new Float64Array(3*nv); for(let k=0;k<nv;k++){ if(rep[k]!==k) continue; let s=[cur[3*k],cur[3*k+1],cur[3*k+2]]; for(const j of nb[k]){s[0]+=cur[3*j];s[1]+=cur[3*j+1];s[2]+=cur[3*j+2];} const l=Math.hypot(...s)||1; for(let c=0;c<3;c++) nx[3*k+c]=s[c]/l;} for(let k=0;k<nv;k++) for(let c=0;c<3;c++) nx[3*k+c]=nx[3*rep[k]+c]; cur=nx;}
  const o=new Int16Array(4*nv); for(let k=0;k<nv;k++) for(let c=0;c<3;c++) o[4*k+c]=Math.round(cur[3*k+c]*H);
  console.log('smoothed',rounds, vb(o));
}
