/* The floor of an EtherCAT round trip over a veth pair: `floor echo IF` answers every 88A4h
 * frame at once (AF_PACKET); `floor master IF PERIOD_NS CYCLES BYTES` sends one frame of BYTES
 * per period (clock_nanosleep to the next period) and prints the round trip p50/p99/max and
 * the late cycles (answer after the next period began): the floor beside scripts/ethercat-chain
 * (scripts/ethercat-floor). */
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
static int open_if(const char *ifn) {
  int s = socket(AF_PACKET, SOCK_RAW, htons(0x88A4));
  struct sockaddr_ll a = {0};
  a.sll_family = AF_PACKET; a.sll_protocol = htons(0x88A4); a.sll_ifindex = if_nametoindex(ifn);
  if (s < 0 || bind(s, (struct sockaddr *)&a, sizeof a) < 0) { perror("socket"); exit(2); }
  return s;
}
static long long ns(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec * 1000000000LL + t.tv_nsec; }
static int cmp(const void *a, const void *b) { long long x = *(long long *)a, y = *(long long *)b; return (x > y) - (x < y); }
int main(int argc, char **argv) {
  unsigned char buf[1600];
  if (argc >= 3 && !strcmp(argv[1], "echo")) {
    int s = open_if(argv[2]);
    for (;;) {
      ssize_t n = recv(s, buf, sizeof buf, 0);
      if (n <= 14) continue;
      if (buf[6] & 0x02) continue; /* our own answer */
      buf[6] |= 0x02;
      send(s, buf, n, 0);
    }
  }
  if (argc < 6) { fprintf(stderr, "usage\n"); return 2; }
  int s = open_if(argv[2]);
  long long period = atoll(argv[3]); int cycles = atoi(argv[4]); int bytes = atoi(argv[5]);
  long long *rt = calloc(cycles, sizeof *rt); int late = 0, got = 0;
  memset(buf, 0, sizeof buf); memset(buf, 0xFF, 6); memset(buf + 6, 0x01, 6); buf[12] = 0x88; buf[13] = 0xA4;
  int len = 14 + bytes; if (len < 60) len = 60;
  struct timespec next; clock_gettime(CLOCK_MONOTONIC, &next);
  for (int i = 0; i < cycles; i++) {
    next.tv_nsec += period; while (next.tv_nsec >= 1000000000) { next.tv_nsec -= 1000000000; next.tv_sec++; }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
    long long due = next.tv_sec * 1000000000LL + next.tv_nsec, t0 = ns();
    send(s, buf, len, 0);
    for (;;) {
      unsigned char r[1600]; struct timeval tv = {0, 100000};
      setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
      ssize_t n = recv(s, r, sizeof r, 0);
      if (n < 0) break;
      if (!(r[6] & 0x02)) continue;
      long long t1 = ns(); rt[got++] = t1 - t0; if (t1 > due + period) late++; break;
    }
  }
  qsort(rt, got, sizeof *rt, cmp);
  printf("%d cycles, %d answered, %d late; round trip p50 %.1f us p99 %.1f us max %.1f us\n", cycles, got, late,
         got ? rt[got / 2] / 1e3 : 0, got ? rt[(int)(got * 0.99)] / 1e3 : 0, got ? rt[got - 1] / 1e3 : 0);
  return 0;
}
