// Summaries the benches print: the mean and a quantile of a list of numbers.

export const mean = (xs) => xs.reduce((a, b) => a + b, 0) / xs.length;

/** The `q` quantile of `xs` (nearest rank below). */
export function quantile(xs, q) {
  const s = [...xs].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.floor(q * s.length))];
}
