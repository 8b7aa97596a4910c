// meshview's view text (client/view/ms_viewer_share.h, docs/VIEWER.md
// "Shareable views") in the page: parsed from #view= and printed into the
// HUD and the URL, so a view copied from either client opens the same in the
// other:
//   mv1:t=X,Y,Z:d=D:o=YAW,PITCH:f=FOVY:u=AXIS[:l=AZ,EL][:s=PLANE/...][:m=POINT/...]
// An object {target, distance, yaw, pitch, fovy, axis (0 x, 1 y, 2 z),
// light: null or {az, el}, sections: [{point, normal}], points: [{anchor,
// direction}]}. Numbers print as meshview prints them: the shortest %g that
// reads back to the same double.
'use strict';

const MsShare = (() => {
  const PITCH_LIMIT = 89 * Math.PI / 180;

  // C's "%.*g" of x with p significant digits.
  function g(x, p) {
    const [mant, exp] = x.toExponential(p - 1).split('e');
    const e = Number(exp);
    if (e < -4 || e >= p) {
      let m = mant.includes('.') ? mant.replace(/0+$/, '').replace(/\.$/, '') : mant;
      return m + 'e' + (e < 0 ? '-' : '+') + String(Math.abs(e)).padStart(2, '0');
    }
    const fixed = x.toFixed(Math.max(0, p - 1 - e));
    return fixed.includes('.') ? fixed.replace(/0+$/, '').replace(/\.$/, '') : fixed;
  }

  // meshview's shortest(): the fewest digits that read back to x, an integer
  // written whole.
  function number(x) {
    if (Object.is(x, -0))
      return '-0';
    let text = '';
    for (let p = 1; p <= 17; ++p) {
      text = g(x, p);
      if (Number(text) === x)
        break;
    }
    if (text.includes('e') && Math.abs(x) >= 1 && Math.abs(x) < 1e17)
      text = x.toFixed(0);
    return text;
  }

  // Exactly n finite decimal numbers separated by sep, else null.
  function numbers(text, sep, n) {
    const parts = text.split(sep);
    if (parts.length !== n)
      return null;
    const out = [];
    for (const p of parts) {
      if (!p || p.length >= 40 || !/^[0-9+\-.eE]+$/.test(p))
        return null;
      const x = Number(p);
      if (!Number.isFinite(x))
        return null;
      out.push(x);
    }
    return out;
  }

  function list(text, each, max) {
    const out = [];
    for (const part of text.split('/')) {
      const v = numbers(part, ',', 6);
      if (!v || out.length === max)
        return null;
      const item = each(v);
      if (!item)
        return null;
      out.push(item);
    }
    return out;
  }

  // The text's state, or {error: one line} as meshview says it.
  function parse(text) {
    const bad = what => ({ error: what + ' (docs/VIEWER.md, "Shareable views")' });
    if (typeof text !== 'string' || text.length >= 4096)
      return bad('missing or longer than 4095 bytes');
    if (!text.startsWith('mv1:'))
      return bad('does not start with mv1:');
    const fields = text.slice(4).split(':');
    const take = key => (fields.length && fields[0].startsWith(key + '=')) ? fields.shift().slice(2) : null;
    const v = { light: null, sections: [], points: [] };
    const t = take('t'), d = take('d'), o = take('o'), f = take('f'), u = take('u');
    if (t === null || !(v.target = numbers(t, ',', 3)))
      return bad('t= wants the orbit centre X,Y,Z');
    const dv = d === null ? null : numbers(d, ',', 1);
    if (!dv || !(dv[0] > 0))
      return bad('d= wants a distance > 0');
    v.distance = dv[0];
    const ov = o === null ? null : numbers(o, ',', 2);
    if (!ov || !(Math.abs(ov[1]) <= PITCH_LIMIT))
      return bad('o= wants YAW,PITCH in radians, |PITCH| at most 89 degrees');
    [v.yaw, v.pitch] = ov;
    const fv = f === null ? null : numbers(f, ',', 1);
    if (!fv || !(fv[0] > 0 && fv[0] < 180))
      return bad('f= wants a field of view in (0, 180) degrees');
    v.fovy = fv[0];
    if (u === null || !/^[xyz]$/.test(u))
      return bad('u= wants x, y or z');
    v.axis = 'xyz'.indexOf(u);
    const l = take('l');
    if (l !== null) {
      const lv = numbers(l, ',', 2);
      if (!lv || !(lv[0] >= -180 && lv[0] <= 180) || !(lv[1] >= -90 && lv[1] <= 90))
        return bad('l= wants AZ,EL in degrees, AZ in [-180, 180], EL in [-90, 90]');
      v.light = { az: lv[0], el: lv[1] };
    }
    const s = take('s');
    if (s !== null) {
      v.sections = list(s, n => {
        const len2 = n[3] * n[3] + n[4] * n[4] + n[5] * n[5];
        const dd = n[0] * n[3] + n[1] * n[4] + n[2] * n[5];
        return len2 > 0 && Number.isFinite(len2) && Number.isFinite(dd) ?
          { point: n.slice(0, 3), normal: n.slice(3) } : null;
      }, 3);
      if (!v.sections)
        return bad('a section plane wants six numbers PX,PY,PZ,NX,NY,NZ, the normal not zero, at most 3 planes');
    }
    const m = take('m');
    if (m !== null) {
      v.points = list(m, n => {
        const len2 = n[3] * n[3] + n[4] * n[4] + n[5] * n[5];
        return len2 > 0 && Number.isFinite(len2) ? { anchor: n.slice(0, 3), direction: n.slice(3) } : null;
      }, 16);
      if (!v.points)
        return bad('a measuring point wants six numbers X,Y,Z,DX,DY,DZ, the direction not zero, at most 16');
    }
    if (fields.length)
      return bad('unknown or misplaced field after u= (l=, s=, then m=, may follow)');
    return v;
  }

  function print(v) {
    const join = a => a.map(number).join(',');
    let text = 'mv1:t=' + join(v.target) + ':d=' + number(v.distance) + ':o=' + join([v.yaw, v.pitch]) +
               ':f=' + number(v.fovy) + ':u=' + 'xyz'[v.axis];
    if (v.light)
      text += ':l=' + join([v.light.az, v.light.el]);
    if (v.sections && v.sections.length)
      text += ':s=' + v.sections.map(s => join([...s.point, ...s.normal])).join('/');
    if (v.points && v.points.length)
      text += ':m=' + v.points.map(p => join([...p.anchor, ...p.direction])).join('/');
    return text;
  }

  return { parse, print, number };
})();
