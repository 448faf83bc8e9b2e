"""How often a two-process gloo run aborts at its end (BENCHMARKS.md §32): VARIANT is ``ddp`` (the model in
DistributedDataParallel), ``allreduce`` (one all_reduce of the gradients instead, its sum not written back:
only the collective matters here) or either with ``-exit``
appended (each process ends with os._exit once its work is done, as wgpu_rt.train.context's
end_data_parallel_process does). Each run trains a small conv net for 20 steps with the collectives the
trainer uses, then barrier and destroy_process_group; the failures are counted and printed.

    python3 scripts/gloo_exit_stress.py VARIANT RUNS     # two at once on 2 cores, as measured
"""

import faulthandler
import os
import socket
import sys

import torch
import torch.distributed as dist


def run(rank: int, port: int, variant: str) -> None:
    faulthandler.enable(all_threads=True)   # an abort prints where the main thread was
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))
    torch.set_num_threads(1)
    dist.init_process_group("gloo", rank=rank, world_size=2)
    model = torch.nn.Sequential(torch.nn.Conv2d(3, 16, 3), torch.nn.ReLU(), torch.nn.Conv2d(16, 3, 3))
    network = torch.nn.parallel.DistributedDataParallel(model) if variant.startswith("ddp") else model
    optimizer = torch.optim.Adam(model.parameters())
    for step in range(20):
        loss = network(torch.rand(2, 3, 32, 32)).square().mean()
        optimizer.zero_grad()
        loss.backward()
        if not variant.startswith("ddp"):
            dist.all_reduce(torch.cat([p.grad.reshape(-1) for p in model.parameters()]))
        optimizer.step()
        dist.broadcast_object_list([step], src=0)
        dist.all_gather_object([None, None], step)
    dist.barrier()
    dist.destroy_process_group()
    if variant.endswith("-exit"):
        sys.stderr.flush()
        os._exit(0)


def main() -> None:
    variant, runs = sys.argv[1], int(sys.argv[2])
    failures = 0
    for _ in range(runs):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        try:
            torch.multiprocessing.spawn(run, args=(port, variant), nprocs=2)
        except Exception as err:   # torch.multiprocessing's ProcessExitedException (SIGABRT)
            failures += 1
            print("FAIL", type(err).__name__, str(err)[:100], flush=True)
    print(f"{variant}: {failures} of {runs} runs failed", flush=True)


if __name__ == "__main__":
    main()
