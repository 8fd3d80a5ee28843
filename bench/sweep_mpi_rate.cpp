// The limit of a sweep spread over many MPI ranks: rank 0 alone receives every finished run and
// appends it to the runs file. This measures that path's rate - probe, receive one row, format it
// as its CSV line, append and flush - with every other rank sending rows as fast as it can, i.e.
// what rank 0 sustains when runs finish faster than it can write them (apps/fluoro/sweep_mpi.cpp
// does the same per row, plus the progress bar when stderr is a terminal).
//   mpirun -n 2 build/bin/fluoro_sweep_mpi_rate [ROWS_PER_SENDER] [OUT.csv]
#include <mpi.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include "pipelines/sweep/sweep.hpp"

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const int rows_per_sender = argc > 1 ? std::atoi(argv[1]) : 200000;
  const std::string out = argc > 2 ? argv[2] : "/tmp/fluoro_sweep_mpi_rate.csv";
  fluoro::SweepRow row;
  row.final_tre_mm = 0.123456789;
  row.initial_tre_mm = 12.3456789;
  row.gradient_correlation = 0.87654321;
  if (rank == 0) {
    std::ofstream csv(out);
    csv << fluoro::sweep_csv_header() << '\n';
    const long total = long(rows_per_sender) * (size - 1);
    MPI_Barrier(MPI_COMM_WORLD);
    const auto t0 = std::chrono::steady_clock::now();
    for (long n = 0; n < total;) {
      int flag = 0;
      MPI_Status status;
      MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
      if (!flag) continue;
      MPI_Recv(&row, int(sizeof row), MPI_BYTE, status.MPI_SOURCE, status.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      row.run.index = int(n);
      csv << fluoro::sweep_csv_row(row) << '\n';
      csv.flush();
      ++n;
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%ld rows from %d senders in %.3f s: %.0f rows/s written and flushed by rank 0\n", total, size - 1, s,
                double(total) / s);
  } else {
    MPI_Barrier(MPI_COMM_WORLD);
    for (int i = 0; i < rows_per_sender; ++i) MPI_Send(&row, int(sizeof row), MPI_BYTE, 0, 3, MPI_COMM_WORLD);
  }
  MPI_Finalize();
  return 0;
}
