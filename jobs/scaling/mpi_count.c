/* MPI call counter (PMPI interposer) for the scaling study: counts the collectives and the
 * point-to-point messages and bytes a run makes, so the communication counts the model takes
 * from the code can be checked against a real run. Built and preloaded by study.sh:
 *   mpicc -shared -fPIC -O2 -o libmpi_count.so mpi_count.c
 *   mpirun -np 2 -x LD_PRELOAD=./libmpi_count.so -x MPI_COUNT_FILE=counts gen4d run DECK
 * At MPI_Finalize every rank writes one line to MPI_COUNT_FILE.<rank> (or stderr):
 *   rank allgather allreduce alltoall alltoallv other_collectives p2p_messages p2p_bytes
 * Point-to-point covers MPI_Send/Isend and persistent sends started with MPI_Start(all)
 * (PETSc's star forests), counted on the sending side. */
#include <mpi.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

static long long n_allgather, n_allreduce, n_alltoall, n_alltoallv, n_other, n_msgs, n_bytes;

/* Persistent send requests: handle -> bytes, open addressing (no deletions needed for the
 * few hundred requests PETSc keeps). */
#define SLOTS 65536
static uintptr_t req_key[SLOTS];
static long long req_bytes[SLOTS];

static size_t slot(uintptr_t k) {
  size_t h = (size_t)((k >> 4) * 0x9e3779b97f4a7c15ULL) & (SLOTS - 1);
  while (req_key[h] != 0 && req_key[h] != k) h = (h + 1) & (SLOTS - 1);
  return h;
}

static long long type_bytes(int count, MPI_Datatype t) {
  int s = 0;
  PMPI_Type_size(t, &s);
  return (long long)count * s;
}

int MPI_Send(const void* b, int c, MPI_Datatype t, int d, int tag, MPI_Comm comm) {
  ++n_msgs;
  n_bytes += type_bytes(c, t);
  return PMPI_Send(b, c, t, d, tag, comm);
}

int MPI_Isend(const void* b, int c, MPI_Datatype t, int d, int tag, MPI_Comm comm,
              MPI_Request* r) {
  ++n_msgs;
  n_bytes += type_bytes(c, t);
  return PMPI_Isend(b, c, t, d, tag, comm, r);
}

int MPI_Send_init(const void* b, int c, MPI_Datatype t, int d, int tag, MPI_Comm comm,
                  MPI_Request* r) {
  int rc = PMPI_Send_init(b, c, t, d, tag, comm, r);
  uintptr_t k = (uintptr_t)*r;
  size_t h = slot(k);
  req_key[h] = k;
  req_bytes[h] = type_bytes(c, t);
  return rc;
}

static void started(MPI_Request r) {
  uintptr_t k = (uintptr_t)r;
  size_t h = slot(k);
  if (req_key[h] == k) {
    ++n_msgs;
    n_bytes += req_bytes[h];
  }
}

int MPI_Start(MPI_Request* r) {
  started(*r);
  return PMPI_Start(r);
}

int MPI_Startall(int n, MPI_Request* r) {
  for (int i = 0; i < n; ++i) started(r[i]);
  return PMPI_Startall(n, r);
}

int MPI_Allgather(const void* sb, int sc, MPI_Datatype st, void* rb, int rc, MPI_Datatype rt,
                  MPI_Comm comm) {
  ++n_allgather;
  return PMPI_Allgather(sb, sc, st, rb, rc, rt, comm);
}

int MPI_Allreduce(const void* sb, void* rb, int c, MPI_Datatype t, MPI_Op op, MPI_Comm comm) {
  ++n_allreduce;
  return PMPI_Allreduce(sb, rb, c, t, op, comm);
}

int MPI_Alltoall(const void* sb, int sc, MPI_Datatype st, void* rb, int rc, MPI_Datatype rt,
                 MPI_Comm comm) {
  ++n_alltoall;
  return PMPI_Alltoall(sb, sc, st, rb, rc, rt, comm);
}

int MPI_Alltoallv(const void* sb, const int* sc, const int* sd, MPI_Datatype st, void* rb,
                  const int* rc, const int* rd, MPI_Datatype rt, MPI_Comm comm) {
  ++n_alltoallv;
  return PMPI_Alltoallv(sb, sc, sd, st, rb, rc, rd, rt, comm);
}

int MPI_Bcast(void* b, int c, MPI_Datatype t, int root, MPI_Comm comm) {
  ++n_other;
  return PMPI_Bcast(b, c, t, root, comm);
}

int MPI_Barrier(MPI_Comm comm) {
  ++n_other;
  return PMPI_Barrier(comm);
}

int MPI_Finalize(void) {
  int rank = 0;
  PMPI_Comm_rank(MPI_COMM_WORLD, &rank);
  const char* base = getenv("MPI_COUNT_FILE");
  FILE* f = stderr;
  char path[4096];
  if (base) {
    snprintf(path, sizeof path, "%s.%d", base, rank);
    f = fopen(path, "w");
    if (!f) {
      fprintf(stderr, "mpi_count: cannot write %s\n", path);
      f = stderr;
    }
  }
  fprintf(f, "%d %lld %lld %lld %lld %lld %lld %lld\n", rank, n_allgather, n_allreduce,
          n_alltoall, n_alltoallv, n_other, n_msgs, n_bytes);
  if (f != stderr) fclose(f);
  return PMPI_Finalize();
}
