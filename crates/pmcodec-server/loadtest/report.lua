-- Shared by lod.lua and chunks.lua (run.sh sets LOADTEST_DIR): the summary both print.
-- wrk counts non-2xx responses itself, so the scripts define no response() callback, which
-- would make wrk hand every body to Lua and spend the load generator's CPU on copies.
function done(summary, latency, requests)
  io.write(string.format("non-2xx responses: %d, socket errors: connect %d read %d write %d timeout %d\n",
    summary.errors.status, summary.errors.connect, summary.errors.read, summary.errors.write, summary.errors.timeout))
  for _, p in ipairs({50, 90, 99, 99.9}) do
    io.write(string.format("p%g: %.2f ms\n", p, latency:percentile(p) / 1000))
  end
end
